"""Queued runs' parsed logs handed from the request to this process's worker in memory.

A queued run's input is always stored (``run_inputs``) before the request is answered: a
worker of any process, or this one after a restart, processes it from there. When this
process's own worker claims the run soon after, it takes the log the request parsed and the
pre-flight's :class:`~engine.pipeline.RunCheck` from here instead: no read-back and unpacking
of the stored log, no second check of it; and the inversion the request started while it
stored the input (:func:`app.services.processing.start_inversion`), when a slot was free.
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
from dataclasses import dataclass

from engine.pipeline import RunCheck
from engine.runlog import RunLog

from .processing import StartedInversion

CAPACITY = 2
"""Most logs held at once."""

TTL_S = 120.0
"""Longest an entry waits for its worker, s."""


@dataclass(frozen=True)
class Handed:
    """A queued run's log as the request parsed it, and what its pre-flight found."""

    identity: str
    """The run's ``content_hash``: guards against another run stored under the same id."""
    log: RunLog
    check: RunCheck
    at: float
    """``time.monotonic()`` when it was handed over, s."""
    inversion: StartedInversion | None = None
    """The inversion of this log already running (None: the worker inverts it)."""


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
        self, run_id: int, identity: str, log: RunLog, check: RunCheck,
        inversion: StartedInversion | None = None,
    ) -> None:  # fmt: skip
        """Hold run ``run_id``'s log (its check, the inversion started) for the worker."""
        with self._lock:
            self._held.pop(run_id, None)
            self._held[run_id] = Handed(identity, log, check, time.monotonic(), inversion)
            self._expire()
            while len(self._held) > self.capacity:
                self._held.popitem(last=False)

    def take(self, run_id: int, identity: str | None = None) -> Handed | None:
        """Remove and return run ``run_id``'s entry (None when there is none, it expired, or
        it was handed over for content other than ``identity``)."""
        with self._lock:
            self._expire()
            handed = self._held.pop(run_id, None)
        if handed is None or (identity is not None and handed.identity != identity):
            return None
        return handed

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
