"""The inversion slots: an inversion starts only in a free slot and frees it."""

from __future__ import annotations

import pytest

from app.services.run_lifecycle.processing import start_inversion
from engine.errors import BudgetExceeded
from engine.setup import RunSetup, prepare_run


def test_an_inversion_is_started_only_in_a_free_slot_and_frees_it(synthetic_run) -> None:
    """No free processing slot: nothing starts (the worker inverts later). Started: the slot
    is held until the inversion ends, and an engine error is handed to whoever takes the
    result."""
    import threading

    from engine.logio import read_run_csv

    slots = threading.BoundedSemaphore(1)
    log = read_run_csv(synthetic_run["csv"])
    run = prepare_run(log, RunSetup(start_chainage_m=synthetic_run["start_chainage_m"]))
    with slots:
        assert start_inversion(slots, run, None) is None
    # a processing budget it cannot meet: the inversion fails (BudgetExceeded)
    started = start_inversion(slots, run, 1e-9)
    assert started is not None
    with pytest.raises(BudgetExceeded):
        started.result()
    assert slots.acquire(timeout=5)  # freed
    slots.release()
    ok = start_inversion(slots, run, None)
    assert ok is not None and ok.result().result.soft_spots
