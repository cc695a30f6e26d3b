"""A load-weigh system's static wheel load as an optional, mapped column of a run log."""

from __future__ import annotations

import io

import numpy as np
import pytest

from engine.errors import LogFormatError
from engine.logio import CsvOptions, parse_run_csv, preview_csv, read_run_csv, write_run_csv
from engine.runlog import RunLog
from engine.vehicle import GRAVITY


def _csv(header: str, load: np.ndarray, n: int = 400) -> bytes:
    rng = np.random.default_rng(1)
    t = np.arange(n) / 500.0
    az = 9.81 + 0.05 * rng.standard_normal(n)
    rows = [header] + [
        f"{t[i]:.4f},{az[i]:.5f},{0.002 * np.sin(i / 9):.6f},{30.0:.3f},{load[i]:.3f}"
        for i in range(n)
    ]
    return ("\n".join(rows) + "\n").encode()


@pytest.mark.parametrize(
    ("name", "scale", "unit"),
    [
        ("wheel_load_kn", 1e-3, "kN"),
        ("static_wheel_load_n", 1.0, "N"),
        ("load_weigh_t", 1.0 / (1e3 * GRAVITY), "t"),
        ("Wheel load [kN]", 1e-3, "kN"),
    ],
)
def test_load_weigh_column_is_recognised_in_its_unit(name: str, scale: float, unit: str) -> None:
    """Names and units of a load-weigh column are recognised; the log carries the load in N and
    its median as the run's static wheel load (the reading jitters with the body's motion)."""
    rng = np.random.default_rng(2)
    load_n = 88_000.0 + 1500.0 * rng.standard_normal(400)
    data = _csv(f"time_s,accel_z_mps2,pitch_rate_radps,speed_mps,{name}", load_n * scale)
    parsed = parse_run_csv(data)
    assert parsed.columns["wheel_load"] == name
    assert parsed.units["wheel_load"] == unit
    assert parsed.log.wheel_load_n is not None
    np.testing.assert_allclose(parsed.log.wheel_load_n, load_n, rtol=1e-4)
    assert parsed.log.static_wheel_load_n() == pytest.approx(np.median(load_n), rel=1e-4)
    preview = preview_csv(data)
    assert preview.mapping["wheel_load"] == name
    assert preview.units["wheel_load"] == unit


def test_a_log_without_load_weigh_has_none() -> None:
    data = _csv("time_s,accel_z_mps2,pitch_rate_radps,speed_mps,temperature_c", np.full(400, 20.0))
    log = read_run_csv(data)
    assert log.wheel_load_n is None
    assert log.static_wheel_load_n() is None


def test_unit_assumed_and_explicit_option_wins() -> None:
    """A bare name is read in kN with a note saying so; wheel_load_unit overrides it."""
    data = _csv("time_s,accel_z_mps2,pitch_rate_radps,speed_mps,wheel_load", np.full(400, 4.0))
    with pytest.raises(LogFormatError) as err:
        read_run_csv(data)  # 4 kN is too light for a rail vehicle's wheel: read as kN
    assert err.value.column == "wheel_load"
    assert "wheel_load_unit" in str(err.value) and "'t'" in str(err.value)
    log = read_run_csv(data, CsvOptions(wheel_load_unit="t"))
    assert log.static_wheel_load_n() == pytest.approx(4.0 * 1e3 * GRAVITY)
    parsed = parse_run_csv(
        _csv("time_s,accel_z_mps2,pitch_rate_radps,speed_mps,wheel_load", np.full(400, 90.0))
    )
    assert any("wheel_load_unit" in note for note in parsed.notes)


def test_implausible_load_names_column_row_and_unit() -> None:
    load = np.full(400, 88.0)
    load[123] = 880.0  # kN: a tenfold reading
    data = _csv("time_s,accel_z_mps2,pitch_rate_radps,speed_mps,wheel_load_kn", load)
    with pytest.raises(LogFormatError) as err:
        read_run_csv(data)
    assert err.value.column == "wheel_load_kn"
    assert err.value.row == 125  # header line 1, sample 0 on line 2
    assert "880 kN" in str(err.value) and "300 kN" in str(err.value)


def test_explicit_column_choice_and_round_trip() -> None:
    data = _csv("time_s,accel_z_mps2,pitch_rate_radps,speed_mps,lw", np.full(400, 101.5))
    assert read_run_csv(data).wheel_load_n is None  # an unknown name is not guessed
    log = read_run_csv(data, CsvOptions(wheel_load_column="lw", wheel_load_unit="kN"))
    assert log.static_wheel_load_n() == pytest.approx(101_500.0)
    buf = io.StringIO()
    write_run_csv(log, buf)
    back = read_run_csv(buf.getvalue().encode())
    assert back.wheel_load_n is not None
    np.testing.assert_array_equal(back.wheel_load_n, log.wheel_load_n)


def test_runlog_checks_the_column_like_the_others() -> None:
    t = np.arange(10) / 100.0
    with pytest.raises(LogFormatError, match="wheel_load_n"):
        RunLog(t, np.zeros(10), np.zeros(10), speed_mps=np.full(10, 20.0),
               wheel_load_n=np.full(9, 8e4))  # fmt: skip
