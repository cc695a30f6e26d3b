"""The app's start-up heap is frozen out of the garbage collector's reach while it runs
(``freeze_startup_heap``, on by default) and given back when it stops."""

from __future__ import annotations

import gc

import pytest

from app.core.config import Settings


@pytest.mark.slow
def test_startup_heap_is_frozen_while_the_app_runs(start_app) -> None:
    assert gc.get_freeze_count() == 0
    client = start_app(freeze_startup_heap=True)
    assert gc.get_freeze_count() > 10_000, "the start-up heap was not frozen"
    assert client.get("/healthz").status_code == 200
    client.__exit__(None, None, None)
    assert gc.get_freeze_count() == 0, "the heap stayed frozen after the app stopped"


def test_tests_skip_the_freeze_and_production_does_not(start_app) -> None:
    start_app()
    assert gc.get_freeze_count() == 0
    assert Settings.model_fields["freeze_startup_heap"].default is True
