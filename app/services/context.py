"""What the services of one app instance share: settings, database, processing slots, and
whom to tell that a run was queued (the worker, which knows the context, not the reverse)."""

from __future__ import annotations

import threading
from collections.abc import Callable
from dataclasses import dataclass, field

from app.core.config import Settings
from app.core.memory import IdleRelease
from app.db.session import Database
from app.services.run_lifecycle.handover import Handover


def _nobody() -> None:
    """No worker in this process: queued runs are found by the workers' polling."""


@dataclass
class AppContext:
    """Per-app services.

    Attributes
    ----------
    slots : BoundedSemaphore
        Caps the inversions running at once in this process (inline and background alike):
        each holds a few hundred MB for a long log.
    on_queued : callable
        Called after a run is queued for the background (the app sets its worker's ``wake``).
    handover : Handover or None
        Where queued runs' parsed logs wait for this process's worker (set while it runs;
        None without a worker: the logs are read back from the database).
    memory : IdleRelease
        Told when a piece of work ends; hands freed memory back once the process is idle
        (``settings.memory_release_idle_s``).
    """

    settings: Settings
    db: Database
    slots: threading.BoundedSemaphore = field(init=False)
    memory: IdleRelease = field(init=False)
    on_queued: Callable[[], None] = _nobody
    handover: Handover | None = None

    def __post_init__(self) -> None:
        self.slots = threading.BoundedSemaphore(self.settings.workers)
        self.memory = IdleRelease(self.settings.memory_release_idle_s)

    def wake_worker(self) -> None:
        """Tell this process's worker a run is queued (other processes find it by polling)."""
        self.on_queued()
