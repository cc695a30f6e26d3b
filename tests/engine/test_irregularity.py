"""Rail geometry: standard spectra, random and given profiles, presets, forward model, CLI."""

import json

import numpy as np
import pytest

from engine.cli import main
from engine.errors import ParameterError
from engine.irregularity import (
    SPECTRA,
    band_sd_mm,
    get_spectrum,
    random_profile,
    read_profile_csv,
)
from engine.synthetic import make_run, make_track
from engine.track import SoftZone, TrackParams
from engine.vehicle import HEAVY, PRESETS, TABLE1, VehicleParams, get_preset
from support.samples import shared_data_dir


def test_registry_has_german_and_fra_spectra_in_si_units():
    """German low/high and FRA 1-6; the FRA A_v is the table's cm² rad/m converted to m²."""
    assert {"german-low", "german-high", *(f"fra-{c}" for c in range(1, 7))} <= set(SPECTRA)
    fra6 = SPECTRA["fra-6"]
    assert fra6.a_v == pytest.approx(0.0339e-4)
    expected = 0.25 * 0.0339e-4 * 0.8245**2 / (1.0 * (1.0 + 0.8245**2))
    assert float(fra6.psd(1.0)) == pytest.approx(expected)
    # smoother classes have less roughness, german-high more than german-low
    sd = [SPECTRA[f"fra-{c}"].sd_m(3, 25) for c in range(1, 7)]
    assert all(a > b for a, b in zip(sd, sd[1:], strict=False))
    assert SPECTRA["german-high"].sd_m(3, 25) > SPECTRA["german-low"].sd_m(3, 25)
    with pytest.raises(ParameterError, match="german-low"):
        get_spectrum("german-medium")


def test_german_low_profile_has_the_documented_level_in_3_25_m():
    """A 600 m german-low profile: ~1 mm SD in 3-25 m (geometry.md: ≈ 0.9 mm), ~1.4 in 3-40."""
    p = random_profile("german-low", 600.0, seed=3)
    assert SPECTRA["german-low"].sd_m(3, 25) == pytest.approx(0.98e-3, rel=0.05)
    assert 0.8 <= band_sd_mm(p.x_m, p.level_m, 3, 25) <= 1.25
    assert 1.1 <= band_sd_mm(p.x_m, p.level_m, 3, 40) <= 1.7


def test_random_profile_is_seeded_and_band_limited():
    """Same seed, same profile; no wavelength outside 1-120 m; scale multiplies amplitudes."""
    a = random_profile("german-high", 960.0, seed=5)
    b = random_profile("german-high", 960.0, seed=5)
    c = random_profile("german-high", 960.0, seed=6)
    h = random_profile("german-high", 960.0, seed=5, scale=0.5)
    assert np.array_equal(a.level_m, b.level_m)
    assert not np.allclose(a.level_m, c.level_m)
    assert np.allclose(h.level_m, 0.5 * a.level_m)
    spec = np.abs(np.fft.rfft(a.level_m[:19200])) ** 2
    k = np.fft.rfftfreq(19200, 0.05)  # cycles/m
    inside = (k >= 1 / 120) & (k <= 1.0)
    assert spec[~inside].sum() < 1e-3 * spec[inside].sum()
    with pytest.raises(ParameterError, match="lambda_min_m"):
        random_profile("german-low", 100.0, lambda_min_m=50.0, lambda_max_m=10.0)


def test_given_profile_csv_and_its_errors(tmp_path):
    """A CSV chainage_m,level_mm is read in m; a bad value names its row and column."""
    good = tmp_path / "g.csv"
    good.write_text("chainage_m,level_mm\n0,0.5\n1,-0.5\n2,1.0\n")
    p = read_profile_csv(good)
    assert np.allclose(p.level_m, [0.5e-3, -0.5e-3, 1e-3])
    assert float(p(np.array([0.5]))[0]) == pytest.approx(0.0)
    bad = tmp_path / "b.csv"
    bad.write_text("chainage_m,level_mm\n0,0.5\n1,abc\n2,1.0\n")
    with pytest.raises(ParameterError, match="row 3, column level_mm"):
        read_profile_csv(bad)
    back = tmp_path / "c.csv"
    back.write_text("chainage_m,level_mm\n0,0.5\n2,0.1\n1,1.0\n")
    with pytest.raises(ParameterError, match="must increase"):
        read_profile_csv(back)


def test_presets_heavy_is_the_public_sets_vehicle_with_twice_the_load():
    """PRESETS: table1 and heavy; heavy matches the public geometry set's truth, 196 kN/axle."""
    assert PRESETS["table1"] is TABLE1 and get_preset("heavy") is HEAVY
    assert HEAVY.static_axle_loads() == pytest.approx((196.2e3, 196.2e3))
    with pytest.raises(ParameterError, match="heavy"):
        get_preset("locomotive")
    d = shared_data_dir()
    truth = d / "geometry" / "geo_heavy_1.truth.json" if d else None
    if truth is None or not truth.exists():
        pytest.skip("public geometry set not available")
    assert VehicleParams.from_dict(json.loads(truth.read_text())["vehicle"]) == HEAVY


def test_forward_model_rides_on_the_unloaded_geometry():
    """The true loaded level = unloaded rail level + the (nominal, ~static) deflection."""
    track = make_track(120.0, irregularity="german-low", seed=2)
    run = make_run(track=track, speed=10.0, start_chainage_m=12.0, sim_rate_hz=500.0,
                   vehicle=HEAVY, start_error_m=1.5)  # fmt: skip
    r = run.track.rail_irregularity(run.sim.x_front)
    w = run.sim.y_front - r
    static = -run.track.params.winkler_deflection(HEAVY.static_axle_loads()[0])
    assert np.std(r) > 1e-3  # millimetres of geometry
    assert np.median(w) == pytest.approx(static, rel=0.08)
    assert np.std(w) < 0.1 * np.std(r)
    assert run.logged_start_chainage_m == pytest.approx(13.5)
    assert run.vehicle is HEAVY and run.irregularity is not None
    assert np.allclose(
        run.true_geometry(np.array([50.0])), 1e3 * run.irregularity(np.array([50.0]))
    )


def test_straight_track_is_unchanged_by_the_geometry_option():
    """Without irregularity make_track gives the same supports as before (same seed, jitter)."""
    track, prof = make_track(100.0, zones=[SoftZone(40, 45, 0.5)], jitter=0.05, seed=4)
    rng = np.random.default_rng(4)
    k = np.full(track.n_supports, 8e7)
    x = track.support_x
    k[(x >= 40 - 1e-9) & (x <= 45 + 1e-9)] *= 0.5
    k = k * np.clip(1.0 + 0.05 * rng.standard_normal(track.n_supports), 0.5, 1.5)
    assert prof is None and np.allclose(track.k, k)
    assert np.all(track.rail_irregularity(x) == 0)


def test_cli_simulates_heavy_vehicle_over_a_spectrum(tmp_path):
    """`simulate --vehicle heavy --spectrum german-low`: truth levels carry the geometry."""
    run, truth = tmp_path / "run.csv", tmp_path / "truth.csv"
    args = ["simulate", "--length", "160", "--speed", "20", "--start-chainage", "20",
            "--vehicle", "heavy", "--spectrum", "german-low", "--irregularity-seed", "4",
            "--out", str(run), "--truth", str(truth)]  # fmt: skip
    assert main(args) == 0
    tr = np.loadtxt(truth, delimiter=",", skiprows=1)
    assert 0.6 <= band_sd_mm(tr[:, 1], tr[:, 2] * 1e-3, 3, 25) <= 1.5
    # heavy static deflection ~ -1.1 mm on 80 kN/mm supports (table1 ~ -0.49)
    ref = random_profile("german-low", 160.0, seed=4)
    w = tr[:, 2] - 1e3 * ref(tr[:, 1])
    static_mm = 1e3 * TrackParams().winkler_deflection(HEAVY.static_axle_loads()[0])
    assert np.median(w) == pytest.approx(-static_mm, rel=0.08)


def test_cli_rejects_unknown_preset_and_both_geometry_inputs(tmp_path, capsys):
    """Unknown preset: argparse names the choices; --spectrum with --irregularity: exit 2."""
    with pytest.raises(SystemExit):
        main(["simulate", "--out", str(tmp_path / "r.csv"), "--vehicle", "tram"])
    assert "heavy" in capsys.readouterr().err
    prof = tmp_path / "p.csv"
    prof.write_text("chainage_m,level_mm\n0,0\n300,0\n")
    rc = main(["simulate", "--out", str(tmp_path / "r.csv"), "--spectrum", "fra-6",
               "--irregularity", str(prof)])  # fmt: skip
    assert rc == 2 and "not both" in capsys.readouterr().err
