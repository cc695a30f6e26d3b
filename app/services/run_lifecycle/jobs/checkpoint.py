"""Copying SQLite's write-ahead log into the database file when there is nothing else to do."""

from __future__ import annotations

import logging
import threading

from app.services.run_lifecycle.jobs.base import Crew, Job

log = logging.getLogger(__name__)


class CheckpointJob(Job):
    """Moves the WAL's pages into the SQLite database file once the worker is idle (not at a
    request's commit: see ``SQLITE_AUTOCHECKPOINT_PAGES``). Cheap when there is nothing to
    copy; one thread of the process at a time."""

    def __init__(self, crew: Crew) -> None:
        super().__init__(crew)
        self._lock = threading.Lock()

    def look(self) -> bool:
        """Checkpoint; always False (it never leaves more work behind)."""
        if not self._lock.acquire(blocking=False):
            return False
        try:
            self.ctx.db.checkpoint()
        except Exception:  # a busy or locked database: the next idle moment tries again
            log.warning("WAL checkpoint failed", exc_info=True)
        finally:
            self._lock.release()
        return False
