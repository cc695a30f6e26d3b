"""Command line: simulate -> invert -> process, with the options of the issues."""

import json
import subprocess
import sys

import numpy as np
import pytest

from engine.cli import main
from support.samples import REPO, shared_data_dir

SIM = ["simulate", "--length", "200", "--speed", "20", "--start-chainage", "24.13",
       "--duration", "7.5", "--zone", "60:65:0.5"]  # fmt: skip


def test_simulate_then_direct_invert_reproduces_truth(tmp_path):
    """The issue's command pair: the direct inverse returns the true levels to <= 1e-6 m."""
    run, truth, levels = tmp_path / "run.csv", tmp_path / "truth.csv", tmp_path / "levels.csv"
    assert main([*SIM, "--out", str(run), "--truth", str(truth)]) == 0
    assert run.read_text().splitlines()[0] == "time_s,accel_z_mps2,pitch_rate_radps,speed_mps"
    assert main(["invert", str(run), "--method", "direct", "--start-chainage", "24.13",
                 "--out", str(levels)]) == 0  # fmt: skip
    lv = np.loadtxt(levels, delimiter=",", skiprows=1)
    tr = np.loadtxt(truth, delimiter=",", skiprows=1)
    header = levels.read_text().splitlines()[0]
    assert header == "time_s,front_chainage_m,front_level_mm,rear_chainage_m,rear_level_mm"
    assert lv.shape == tr.shape == (7501, 5)
    assert np.allclose(lv[:, 1], tr[:, 1]) and np.allclose(lv[:, 3], tr[:, 3])
    assert np.max(np.abs(lv[:, 2] - (tr[:, 2] - tr[0, 2]))) * 1e-3 <= 1e-6
    assert np.max(np.abs(lv[:, 4] - (tr[:, 4] - tr[0, 4]))) * 1e-3 <= 1e-6


def test_process_writes_profile_and_soft_spots(tmp_path):
    """`process` writes profile.csv on a <= 0.25 m grid and the zone in soft_spots.json."""
    run = tmp_path / "run.csv"
    assert main([*SIM, "--accel-noise", "0.005", "--gyro-noise", "1e-4", "--accel-bias",
                 "0.02", "--gyro-bias", "2e-4", "--digits", "8", "--seed", "3",
                 "--out", str(run)]) == 0  # fmt: skip
    out = tmp_path / "out"
    assert main(["process", str(run), "--start-chainage", "24.13", "--out", str(out)]) == 0
    prof = np.loadtxt(out / "profile.csv", delimiter=",", skiprows=1)
    assert (out / "profile.csv").read_text().startswith("chainage_m,level_mm")
    assert np.all(np.diff(prof[:, 0]) <= 0.25 + 1e-9)
    spots = json.loads((out / "soft_spots.json").read_text())
    assert len(spots) == 1
    assert set(spots[0]) == {"start_m", "end_m", "peak_m", "depth_mm", "stiffness_loss_pct"}
    assert abs(spots[0]["start_m"] - 60) <= 1.5 and abs(spots[0]["end_m"] - 65) <= 1.5
    assert abs(spots[0]["stiffness_loss_pct"] - 50) <= 10


def test_invert_sample_clean_exact(tmp_path):
    """`invert --method direct` on the shared exact sample matches its truth to 1e-6 m."""
    d = shared_data_dir()
    if d is None:
        pytest.skip("shared samples not available")
    out = tmp_path / "levels.csv"
    assert main(["invert", str(d / "sample_clean_exact.csv"), "--method", "direct",
                 "--start-chainage", "24.13", "--out", str(out)]) == 0  # fmt: skip
    lv = np.loadtxt(out, delimiter=",", skiprows=1)
    truth = np.load(d / "sample_clean_exact.truth.npz")
    assert np.max(np.abs(lv[:, 2] * 1e-3 - (truth["r1"] - truth["r1"][0]))) <= 1e-6
    assert np.max(np.abs(lv[:, 4] * 1e-3 - (truth["r2"] - truth["r2"][0]))) <= 1e-6
    assert np.allclose(lv[:, 1], truth["x_front"], atol=1e-6)


def test_bad_input_exit_code_and_message(tmp_path, capsys):
    """A bad option value is reported on stderr with exit code 2, naming the problem."""
    assert main([*SIM[:-2], "--zone", "65:60:0.5", "--out", str(tmp_path / "x.csv")]) == 2
    assert "soft zone" in capsys.readouterr().err
    assert main(["invert", str(tmp_path / "missing.csv"), "--out", str(tmp_path / "y")]) == 2


@pytest.mark.parametrize("cmd", ["simulate", "invert", "process"])
def test_help_states_units(cmd):
    """`--help` of each command runs as a module and states units."""
    out = subprocess.run([sys.executable, "-m", "engine", cmd, "--help"], capture_output=True,
                         text=True, cwd=REPO, check=True).stdout  # fmt: skip
    assert " m" in out or "m/s" in out


@pytest.mark.slow
def test_simulate_with_a_sensor_grade_and_process_writes_its_detection_limit(tmp_path, capsys):
    """`simulate --sensor-grade` logs the grade's noise (as the inversion measures it);
    `process` writes the pass's detection limit; typed figures with a grade are refused."""
    quiet, noisy = tmp_path / "fibre.csv", tmp_path / "consumer.csv"
    limits = []
    for grade, run in (("fibre-optic", quiet), ("consumer-mems", noisy)):
        assert main([*SIM, "--sensor-grade", grade, "--seed", "4", "--out", str(run)]) == 0
        out = tmp_path / grade
        assert main(["process", str(run), "--start-chainage", "24.13", "--out", str(out)]) == 0
        q = json.loads((out / "quality.json").read_text())
        lim = json.loads((out / "detection_limit.json").read_text())
        assert lim["zone_length_m"] == [3.0, 6.0]
        limits.append((q["noise_accel_mps2"], lim["min_loss_pct"][0]))
    (na_q, lim_q), (na_n, lim_n) = limits
    assert na_q == pytest.approx(0.005, rel=0.1) and na_n == pytest.approx(0.050, rel=0.1)
    assert lim_n > lim_q
    assert main([*SIM, "--sensor-grade", "tactical-mems", "--accel-noise", "0.01",
                 "--out", str(tmp_path / "x.csv")]) == 2  # fmt: skip
    assert "--sensor-grade" in capsys.readouterr().err
