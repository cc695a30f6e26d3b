"""engine.plausibility: one check for every input path (the probe's JSON logs)."""

from __future__ import annotations

import io

import numpy as np
import pytest

import engine.plausibility as plausibility_mod
from engine.errors import LogFormatError
from engine.logio import read_run_csv, write_run_csv
from engine.plausibility import check_plausible
from engine.runlog import RunLog
from engine.setup import RunSetup, prepare_run


def _log(n: int = 4000, rate: float = 1000.0, v: float = 25.0, chainage: bool = False) -> RunLog:
    rng = np.random.default_rng(0)
    t = np.arange(n) / rate
    c = 12.0 + v * t
    return RunLog(
        time_s=t,
        accel_z_mps2=0.1 * rng.standard_normal(n),
        pitch_rate_radps=0.01 * rng.standard_normal(n),
        speed_mps=None if chainage else np.full(n, v),
        chainage_m=c if chainage else None,
    )


def _with(log: RunLog, **arrays: np.ndarray) -> RunLog:
    fields = {k: getattr(log, k) for k in ("time_s", "accel_z_mps2", "pitch_rate_radps",
                                           "speed_mps", "chainage_m")}  # fmt: skip
    return RunLog(**(fields | arrays))


def test_a_plausible_log_passes() -> None:
    check_plausible(_log())
    check_plausible(_log(chainage=True))


def _edited(name: str, i: int, value: float, chainage: bool = False) -> RunLog:
    log = _log(chainage=chainage)
    arr = getattr(log, name).copy()
    arr[i] = value
    return _with(log, **{name: arr})


@pytest.mark.parametrize(
    ("make", "column", "row", "words"),
    [
        (lambda: _with(_log(), time_s=np.arange(4000) / 1e3 + 100 * (np.arange(4000) >= 99)),
         "time_s", 101, "gap"),
        (lambda: _edited("accel_z_mps2", 56, 1e308), "accel_z_mps2", 58, "50 m/s²"),
        (lambda: _edited("pitch_rate_radps", 88, -6.0), "pitch_rate_radps", 90, "5 rad/s"),
        (lambda: _edited("speed_mps", 75, 1e308), "speed_mps", 77, "150 m/s"),
        (lambda: _with(_log(chainage=True),
                       chainage_m=12 + 25 * np.arange(4000) / 1e3 + 1e6 * (np.arange(4000) >= 200)),
         "chainage_m", 202, "jumps"),
    ],
)  # fmt: skip
def test_implausible_logs_are_refused_naming_column_and_row(make, column, row, words) -> None:
    """The probe's JSON logs (a 100 s gap, 1e308 samples, a 1e6 m chainage jump) are refused
    by the check every path shares, and by the inversion's pre-flight which calls it."""
    log = make()
    for check in (check_plausible, lambda lg: prepare_run(lg, RunSetup(start_chainage_m=12.0))):
        with pytest.raises(LogFormatError) as e:
            check(log)
        assert (e.value.column, e.value.row) == (column, row)
        assert words in str(e.value)
    # The CSV reader's column checks stand for this check (it marks its logs as checked):
    # the same log written as a CSV is refused at the same column and line.
    buf = io.StringIO()
    write_run_csv(log, buf, digits=17)
    with pytest.raises(LogFormatError) as e:
        read_run_csv(buf.getvalue().encode())
    assert (e.value.column, e.value.row) == (column, row)


def test_a_log_is_checked_once_per_preparation(monkeypatch) -> None:
    """check_plausible keeps no memory of logs it saw (each call checks); prepare_run checks
    the log once, unless its reader made the same checks (the CSV reader: log_checked)."""
    calls: list[int] = []
    real = plausibility_mod.check_time_steps
    monkeypatch.setattr(plausibility_mod, "check_time_steps",
                        lambda *a, **k: calls.append(1) or real(*a, **k))  # fmt: skip
    log = _log()
    check_plausible(log)
    check_plausible(log)
    assert len(calls) == 2
    run = prepare_run(log, RunSetup(start_chainage_m=12.0))
    assert len(calls) == 3 and run.log is log
    buf = io.StringIO()
    write_run_csv(log, buf)
    parsed = read_run_csv(buf.getvalue().encode())
    calls.clear()
    prepare_run(parsed, RunSetup(start_chainage_m=12.0), log_checked=True)
    assert calls == []


def test_names_and_rows_can_be_the_files() -> None:
    with pytest.raises(LogFormatError) as e:
        check_plausible(_edited("accel_z_mps2", 9, 99.0), {"accel_z_mps2": "az"}, lambda i: i + 7)
    assert (e.value.column, e.value.row) == ("az", 16)
