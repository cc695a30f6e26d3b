"""The inversion slots: an inversion starts only in a free slot and frees it."""

from __future__ import annotations

import pytest

from app.services.processing import start_inversion
from engine.errors import BudgetExceeded
from engine.pipeline import check_run
from engine.track import TrackParams
from engine.vehicle import TABLE1


def test_an_inversion_is_started_only_in_a_free_slot_and_frees_it(synthetic_run) -> None:
    """No free processing slot: nothing starts (the worker inverts later). Started: the slot
    is held until the inversion ends, and an engine error is handed to whoever takes the
    result."""
    import threading

    from engine.logio import read_run_csv

    slots = threading.BoundedSemaphore(1)
    log = read_run_csv(synthetic_run["csv"])
    start = synthetic_run["start_chainage_m"]
    inputs = dict(start_chainage_m=start, direction="increasing", vehicle=TABLE1,
                  track=TrackParams(), budget_s=None)  # fmt: skip
    with slots:
        assert start_inversion(slots, log, checked=check_run(log, start_chainage_m=start),
                               **inputs) is None  # fmt: skip
    # a processing budget it cannot meet: the inversion fails (BudgetExceeded)
    started = start_inversion(slots, log, checked=check_run(log, start_chainage_m=start),
                              **{**inputs, "budget_s": 1e-9})  # fmt: skip
    assert started is not None
    with pytest.raises(BudgetExceeded):
        started.result()
    assert slots.acquire(timeout=5)  # freed
    slots.release()
    ok = start_inversion(slots, log, checked=check_run(log, start_chainage_m=start), **inputs)
    assert ok is not None and ok.matches(start, "increasing", TABLE1, TrackParams())
    assert not ok.matches(start + 1.0, "increasing", TABLE1, TrackParams())
    assert ok.result().result.soft_spots
