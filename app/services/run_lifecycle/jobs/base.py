"""What every kind of job is: a class the worker makes once, and what it may ask the worker."""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Hashable
from typing import Any, ClassVar, Protocol, TypeVar

from sqlalchemy.orm import Session

from app.services.context import AppContext
from app.services.errors import engine_error_facts
from app.services.run_lifecycle.lease import Claimable
from engine.errors import EngineError

log = logging.getLogger(__name__)
T = TypeVar("T")
J = TypeVar("J", bound="Job")


class Crew(Protocol):
    """The worker as its jobs see it."""

    ctx: AppContext
    id: str
    """The worker's claim mark (:func:`~app.services.run_lifecycle.lease.new_owner`)."""

    def wake(self) -> None:
        """Look for queued work now instead of at the next poll."""

    def job(self, kind: type[J]) -> J:
        """This worker's job of kind ``kind`` (jobs that share state reach each other here)."""


class Job:
    """A kind of work of the worker, made once per worker (it keeps its state between looks).

    A job that works on queued rows names their table in ``claims``: the worker claims a row
    (:mod:`~app.services.run_lifecycle.lease`) and calls :meth:`run` with its id. A job with
    ``claims = None`` finds its own work when the worker looks (:meth:`look`).
    """

    claims: ClassVar[Claimable | None] = None

    def __init__(self, crew: Crew) -> None:
        self.crew = crew
        self.ctx = crew.ctx

    def run(self, job_id: int) -> None:
        """Do the work of claimed row ``job_id`` and store its outcome."""
        raise NotImplementedError

    def unclaimed(self, looked_at: float) -> None:
        """Told that a look started at ``looked_at`` (``time.monotonic()``) found no row to
        claim."""

    def look(self) -> bool:
        """Do one piece of this work if some waits; True when it did (more may wait)."""
        return False


class Retries:
    """Idle work that failed, by key, tried again only after ``retry_s`` (s): a failure that
    repeats does not take every look."""

    def __init__(self, retry_s: float) -> None:
        self.retry_s = retry_s
        self._failed: dict[Hashable, float] = {}  # key: time.monotonic() of its failure

    def due(self, key: Hashable) -> bool:
        """Whether ``key``'s work may be tried (never failed, or failed ``retry_s`` ago)."""
        failed_at = self._failed.get(key)
        return failed_at is None or time.monotonic() - failed_at > self.retry_s

    def attempt(self, key: Hashable, doing: str, work: Callable[[], bool]) -> bool:
        """``work()``'s answer; False when it raised (logged as ``doing``, ``key`` then waits
        ``retry_s``)."""
        try:
            done = work()
        except Exception:
            log.exception("%s failed", doing)
            self._failed[key] = time.monotonic()
            return False
        self._failed.pop(key, None)
        return done


def failure_facts(exc: Exception, doing: str) -> dict[str, Any]:
    """What a job that failed records: an engine error by its facts, anything else as an
    internal error with the exception's message (its cause, for whoever reads the job)."""
    if isinstance(exc, EngineError):
        return engine_error_facts(exc)
    cause = str(exc)[:500]
    return {
        "message": f"internal error while {doing} ({type(exc).__name__}"
        + (f": {cause})" if cause else ")"),
        "kind": "InternalError",
    }


def attempt(
    ctx: AppContext,
    doing: str,
    job_id: int,
    fail: Callable[[Session, int, dict[str, Any]], None],
    work: Callable[[], T],
) -> T | None:
    """Run a claimed job's numerics; when they fail, record why with ``fail`` (an engine error
    by its facts, anything else as an internal error, logged) and return None."""
    try:
        return work()
    except EngineError as exc:
        facts = engine_error_facts(exc)
    except Exception as exc:
        log.exception("%s %s failed", doing, job_id)
        facts = failure_facts(exc, doing)
    with ctx.db.session() as s:
        fail(s, job_id, facts)
    return None
