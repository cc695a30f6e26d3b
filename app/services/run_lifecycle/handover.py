"""Queued runs' prepared logs handed from the request to this process's worker in memory.

A queued run's input is always stored (``run_inputs``) before the request is answered: a
worker of any process, or this one after a restart, processes it from there. When this
process's own worker claims the run soon after, it takes the request's
:class:`~engine.setup.PreparedRun` (the parsed log, checked with the run's set-up) from here
instead: no read-back and unpacking of the stored log, no second check of it; and the
inversion the request started while it stored the input
(:func:`app.services.run_lifecycle.processing.start_inversion`), when a slot was free. The entry is
the
run's: run ids are never reused (``AUTOINCREMENT`` on SQLite, a sequence on PostgreSQL).
Bounded: at most ``capacity`` logs are held (each a few hundred MB for a long log), an entry
is removed when taken, and dropped when newer ones push it out, it waited ``ttl_s``
unclaimed, or the worker found no run it could claim (its run was claimed by another
process, deleted or failed: :meth:`Handover.drop_before`); a missing entry only means the
stored input is read (and inverted again).
"""

from __future__ import annotations

import threading
import time
from collections import OrderedDict
from concurrent.futures import Future
from dataclasses import dataclass

from app.services.run_lifecycle.processing import Processed
from engine.setup import PreparedRun, RunSetup

CAPACITY = 2
"""Most logs held at once."""

TTL_S = 120.0
"""Longest an entry waits for its worker, s."""


@dataclass(frozen=True)
class Handed:
    """A queued run as the request prepared it, and its inversion if one was started."""

    prepared: PreparedRun
    at: float
    """``time.monotonic()`` when it was handed over, s."""
    inversion: Future[Processed] | None = None
    """The inversion of ``prepared`` already running (None: the worker inverts it)."""

    def started_for(self, setup: RunSetup) -> Future[Processed] | None:
        """The started inversion when it is of ``setup`` (the run's set-up when claimed: a
        vehicle version registered since changes it), else None."""
        return self.inversion if setup == self.prepared.setup else None


class Handover:
    """Logs of runs queued by this process, by run id, for this process's worker."""

    def __init__(self, capacity: int = CAPACITY, ttl_s: float = TTL_S) -> None:
        self.capacity, self.ttl_s = capacity, ttl_s
        self._lock = threading.Lock()
        self._held: OrderedDict[int, Handed] = OrderedDict()

    def __len__(self) -> int:
        with self._lock:
            return len(self._held)

    def put(
        self, run_id: int, prepared: PreparedRun, inversion: Future[Processed] | None = None
    ) -> None:
        """Hold run ``run_id``'s prepared log (and the inversion started) for the worker."""
        with self._lock:
            self._held.pop(run_id, None)
            self._held[run_id] = Handed(prepared, time.monotonic(), inversion)
            self._expire()
            while len(self._held) > self.capacity:
                self._held.popitem(last=False)

    def take(self, run_id: int) -> Handed | None:
        """Remove and return run ``run_id``'s entry (None when there is none or it expired)."""
        with self._lock:
            self._expire()
            return self._held.pop(run_id, None)

    def drop_before(self, t: float) -> int:
        """Drop the entries handed over before ``t`` (``time.monotonic()``, s); how many.

        The worker calls it when no run was claimable in a look that started at ``t``: the
        runs of those entries are in another process's hands (or gone), and their logs would
        otherwise stay held until the next upload of this process.
        """
        with self._lock:
            old = [k for k, h in self._held.items() if h.at < t]
            for run_id in old:
                del self._held[run_id]
        return len(old)

    def clear(self) -> None:
        """Drop every entry."""
        with self._lock:
            self._held.clear()

    def _expire(self) -> None:
        oldest = time.monotonic() - self.ttl_s
        for run_id in [k for k, h in self._held.items() if h.at < oldest]:
            del self._held[run_id]
