"""Claims on queued work, safe with several app processes on one database.

A queue is a table whose rows carry ``claimed_by``, ``heartbeat_at`` and ``attempts``
(:class:`Claimable`: runs, calibrations). A worker claims a row with one atomic
``UPDATE ... WHERE claimed_by IS NULL OR heartbeat_at < stale`` (only one process can win),
keeps the claim alive with a :class:`Heartbeat` while it works (the lease is
``settings.lease_s``), and writes its result only while it still owns the claim. A process
that dies leaves a claim whose heartbeat stops: another worker takes the row over when the
lease runs out, or this host frees it at once after a restart (:func:`release_dead_claims`).
"""

from __future__ import annotations

import logging
import os
import socket
import threading
import uuid
from dataclasses import dataclass, field
from datetime import timedelta
from typing import Any

from sqlalchemy import ColumnElement, or_, select, update

from app.db.base import utcnow
from app.db.models import Calibration, Run
from app.services.context import AppContext

log = logging.getLogger(__name__)

Queued = type[Run] | type[Calibration]
"""A table of queued work."""


@dataclass(frozen=True)
class Claimable:
    """A table of queued work and the states its rows go through.

    Attributes
    ----------
    model : Run or Calibration
        The table.
    waiting : tuple of str
        States of a row that waits for a worker or is being worked on (a claim that is free
        or stale in one of them can be taken).
    claimed_state : str
        The state of a row while a worker holds it.
    on_claim : dict
        Columns set when a worker claims a row (besides the claim itself).
    on_release : dict
        Columns set when the claim of a dead process is freed.
    batch : int
        Candidates read per look (the first one whose claim succeeds is taken).
    """

    model: Queued
    waiting: tuple[str, ...]
    claimed_state: str
    on_claim: dict[str, Any] = field(default_factory=dict)
    on_release: dict[str, Any] = field(default_factory=dict)
    batch: int = 8

    def claimable(self, lease_s: float) -> ColumnElement[bool]:
        """Rows a worker may claim now: waiting, and free or abandoned ``lease_s`` ago."""
        m = self.model
        stale = utcnow() - timedelta(seconds=lease_s)
        return m.status.in_(self.waiting) & or_(m.claimed_by.is_(None), m.heartbeat_at < stale)


def new_owner() -> str:
    """A worker's claim mark: ``host:pid:random`` (the host and pid make recovery possible)."""
    return f"{socket.gethostname()}:{os.getpid()}:{uuid.uuid4().hex[:8]}"


def claim(ctx: AppContext, owner: str, queue: Claimable) -> int | None:
    """Claim the oldest claimable row of ``queue`` for ``owner``; its id, None when none waits."""
    m = queue.model
    free = queue.claimable(ctx.settings.lease_s)
    with ctx.db.engine.connect() as conn:
        candidates = conn.execute(
            select(m.id).where(free).order_by(m.id).limit(queue.batch)
        ).scalars().all()  # fmt: skip
    for row_id in candidates:
        with ctx.db.engine.begin() as conn:
            res = conn.execute(
                update(m)
                .where(m.id == row_id, free)
                .values(claimed_by=owner, heartbeat_at=utcnow(), attempts=m.attempts + 1,
                        **queue.on_claim)
            )  # fmt: skip
        if res.rowcount == 1:
            return int(row_id)
    return None


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def _dead_local(claimed_by: object, owner: str, host: str) -> bool:
    """True for a claim of another process on this host that no longer runs."""
    parts = str(claimed_by).split(":")
    if len(parts) != 3 or parts[0] != host or claimed_by == owner:
        return False
    try:
        pid = int(parts[1])
    except ValueError:
        return False
    return pid == os.getpid() or not _pid_alive(pid)


def release_dead_claims(ctx: AppContext, owner: str, queues: list[Claimable]) -> int:
    """Free the claims of processes on this host that no longer run; returns how many.

    Their rows are then taken by the next free worker and worked on from their stored input
    (from the start). Claims of other hosts are left to expire (``lease_s``).
    """
    host = socket.gethostname()
    freed = 0
    with ctx.db.engine.begin() as conn:
        for queue in queues:
            m = queue.model
            rows = conn.execute(
                select(m.id, m.claimed_by).where(
                    m.status == queue.claimed_state, m.claimed_by.is_not(None)
                )
            ).all()
            for row_id, claimed_by in rows:
                if _dead_local(claimed_by, owner, host):
                    res = conn.execute(
                        update(m)
                        .where(m.id == row_id, m.claimed_by == claimed_by)
                        .values(claimed_by=None, **queue.on_release)
                    )
                    freed += res.rowcount
    if freed:
        log.warning("resuming %d run(s)/calibration(s) interrupted by a stopped process", freed)
    return freed


class Heartbeat:
    """Refreshes a claim every ``interval`` seconds until stopped (a context manager)."""

    def __init__(
        self, ctx: AppContext, queue: Claimable, row_id: int, owner: str, interval: float
    ) -> None:
        self.ctx, self.row_id, self.owner, self.interval = ctx, row_id, owner, interval
        self.model = queue.model
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._beat, name=f"heartbeat-{row_id}", daemon=True)

    @classmethod
    def of(cls, ctx: AppContext, queue: Claimable, row_id: int, owner: str) -> Heartbeat:
        """The heartbeat of a claim, four beats per lease (at most two a second)."""
        return cls(ctx, queue, row_id, owner, max(0.5, ctx.settings.lease_s / 4))

    def __enter__(self) -> Heartbeat:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join()

    def _beat(self) -> None:
        while not self._stop.wait(self.interval):
            try:
                with self.ctx.db.engine.begin() as conn:
                    m = self.model
                    conn.execute(
                        update(m)
                        .where(m.id == self.row_id, m.claimed_by == self.owner)
                        .values(heartbeat_at=utcnow())
                    )
            except Exception:  # a missed beat only shortens the lease
                log.warning("heartbeat of %s %s failed", self.model.__tablename__, self.row_id,
                            exc_info=True)  # fmt: skip
