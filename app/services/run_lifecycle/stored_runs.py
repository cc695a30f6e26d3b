"""Stored runs: lookup, state checks, listing, soft spots, the profile window, deletion.

Chainage handed out is aligned (the run's stored chainage plus :attr:`Run.offset_m`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from datetime import datetime
from typing import Any

from sqlalchemy import func, select
from sqlalchemy.orm import Session, undefer

from app.db.models import Run, RunSignals, SoftSpot
from app.services.errors import Conflict, Invalid, NotFound
from app.services.storage.profiles import PROFILE_COLUMNS, json_columns, profile_arrays
from app.services.storage.retention import require_detail
from app.services.track.integrate import remove_run_from_track
from app.services.track.separation_store import run_stiffness_basis
from app.services.views.signals import unpack_signals
from app.services.views.window import Window

EXTRA_PROFILE_COLUMNS = PROFILE_COLUMNS[2:]
"""Arrays a profile answer carries on request (``include``), besides chainage and level."""


def get_run(session: Session, run_id: int) -> Run:
    """The run numbered ``run_id``; :class:`NotFound` when there is none."""
    run = session.get(Run, run_id)
    if run is None:
        raise NotFound(f"run {run_id} not found", field="run_id")
    return run


def delete_run(session: Session, run: Run) -> None:
    """Delete ``run`` with its profile, soft spots and signals, its share of its track's
    aggregate recomputed in the same transaction (the caller commits)."""
    remove_run_from_track(session, run)
    session.delete(run)


def require_done(run: Run, what: str) -> None:
    """:class:`Conflict` naming the run's state unless it is processed (``what``: the thing
    asked for, for the message)."""
    if run.status == "processing":
        raise Conflict(
            f"run {run.id} is still processing; its {what} is not available yet",
            status=run.status,
        )
    if run.status == "failed":
        msg = (run.error or {}).get("message", "unknown error")
        raise Conflict(f"run {run.id} failed ({msg}); it has no {what}", status=run.status)


def done_run(session: Session, run_id: int, what: str = "profile") -> Run:
    """The run, processed; :class:`NotFound` or :class:`Conflict` otherwise."""
    run = get_run(session, run_id)
    require_done(run, what)
    return run


def detail_run(session: Session, run_id: int, what: str = "profile") -> Run:
    """The run, processed and with its detail kept; :class:`NotFound`, :class:`Conflict`
    or :class:`Gone` (expired under the retention policy) otherwise."""
    run = done_run(session, run_id, what)
    require_detail(session, run, what)
    return run


def list_runs(
    session: Session,
    *,
    track_id: int | None = None,
    status: str | None = None,
    recorded_from: datetime | None = None,
    recorded_to: datetime | None = None,
    offset: int = 0,
    limit: int = 50,
) -> tuple[Sequence[Run], int]:
    """Runs newest recording first (creation time when unknown), and how many match."""
    conds = []
    if track_id is not None:
        conds.append(Run.track_id == track_id)
    if status is not None:
        conds.append(Run.status == status)
    if recorded_from is not None:
        conds.append(Run.recorded_at >= recorded_from)
    if recorded_to is not None:
        conds.append(Run.recorded_at <= recorded_to)
    count = session.scalar(select(func.count()).select_from(Run).where(*conds)) or 0
    when = func.coalesce(Run.recorded_at, Run.created_at)
    rows = session.scalars(
        select(Run).where(*conds).order_by(when.desc(), Run.id.desc()).offset(offset).limit(limit)
    ).all()
    return rows, int(count)


def included_columns(names: Sequence[str]) -> tuple[str, ...]:
    """The extra profile arrays asked for (``"all"`` for every one), in their stored order;
    :class:`Invalid` naming unknown ones."""
    if "all" in names:
        return EXTRA_PROFILE_COLUMNS
    unknown = [n for n in names if n not in EXTRA_PROFILE_COLUMNS]
    if unknown:
        raise Invalid(
            f"include: unknown column(s) {', '.join(map(repr, unknown))}; choose from "
            f"{', '.join(EXTRA_PROFILE_COLUMNS)} or 'all'",
            field="include",
        )
    return tuple(c for c in EXTRA_PROFILE_COLUMNS if c in names)


def profile_window(
    session: Session, run: Run, window: Window, columns: tuple[str, ...]
) -> dict[str, Any]:
    """A processed run's profile columns in a window, chainage aligned (JSON-ready)."""
    off = run.offset_m
    lo, hi = window.stored(off)
    cols = json_columns(profile_arrays(session, run.id, lo, hi, columns))
    require_detail(session, run, "profile")  # a sweep may have removed it meanwhile
    chainage = cols["chainage_m"] if off == 0 else [c + off for c in cols["chainage_m"]]
    return {
        "run_id": run.id,
        "chainage_offset_m": off,
        "n": len(chainage),
        "chainage_m": chainage,
        **{k: cols[k] for k in columns[1:]},
    }


@dataclass(frozen=True)
class SpotOnTrack:
    """A run's soft spot on aligned chainage (m), depth mm, stiffness loss % (None: unknown)."""

    start_m: float
    end_m: float
    peak_m: float
    depth_mm: float
    stiffness_loss_pct: float | None
    stiffness_basis: str | None = None
    """"single pass" when the loss rests on this run alone over rail smooth at the noise level."""
    message: str | None = None
    """Why no loss is given (one load cannot tell rail geometry from stiffness)."""


def soft_spots(session: Session, run: Run) -> list[SpotOnTrack]:
    """A run's soft spots by chainage, aligned; dips by depth only (loss None, with the
    message) where one pass cannot tell rail geometry from support stiffness."""
    off = run.offset_m
    rows = session.scalars(
        select(SoftSpot).where(SoftSpot.run_id == run.id).order_by(SoftSpot.start_m)
    ).all()
    basis, message = run_stiffness_basis(run.single_pass_valid)
    withheld = basis == "not separable"
    return [
        SpotOnTrack(
            s.start_m + off,
            s.end_m + off,
            s.peak_m + off,
            s.depth_mm,
            None if withheld else s.stiffness_loss_pct,
            "single pass" if basis == "single pass" else None,
            message,
        )  # fmt: skip
        for s in rows
    ]


def signal_data(sig: RunSignals) -> dict[str, list[float | None]]:
    """A run's stored display signals by name (equal-length lists, None = no value)."""
    return unpack_signals(sig.packed) if sig.packed is not None else {}


def signals(session: Session, run: Run) -> RunSignals:
    """The display signals stored with a run; :class:`NotFound` when there are none."""
    require_detail(session, run, "signals")
    # one statement for the row and its (deferred) data: a sweep committing between two
    # would leave the row without its data
    sig = session.scalar(
        select(RunSignals).options(undefer(RunSignals.packed)).where(RunSignals.run_id == run.id)
    )
    if sig is None:
        require_detail(session, run, "signals")
        raise NotFound(f"run {run.id} has no stored signals", field="run_id")
    return sig
