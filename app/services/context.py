"""What the services of one app instance share: settings, database, processing slots, worker."""

from __future__ import annotations

import threading
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from app.core.config import Settings
from app.db.session import Database

if TYPE_CHECKING:
    from .worker import Worker


@dataclass
class AppContext:
    """Per-app services.

    Attributes
    ----------
    slots : BoundedSemaphore
        Caps the inversions running at once in this process (inline and background alike):
        each holds a few hundred MB for a long log.
    """

    settings: Settings
    db: Database
    slots: threading.BoundedSemaphore = field(init=False)
    worker: Worker | None = None

    def __post_init__(self) -> None:
        self.slots = threading.BoundedSemaphore(self.settings.workers)

    def wake_worker(self) -> None:
        """Tell this process's worker a run is queued (other processes find it by polling)."""
        if self.worker is not None:
            self.worker.wake()
