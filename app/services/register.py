"""A track's soft-spot register and its limits.

The register is built on request (``engine.register.build_register``) from the stored soft
spots of the track's merged runs (reference or aligned), shifted by each run's offset, with
each run's aligned extent as its coverage and its recording time (upload time when unknown)
as the time of its observations. Limits are stored per track; a track without its own uses
the engine's defaults.
"""

from __future__ import annotations

from dataclasses import fields
from datetime import datetime

from sqlalchemy import select
from sqlalchemy.orm import Session

from app.db.models import Run, SoftSpot, TrackLimits
from engine.register import Defect, Limits, Observation, RunCoverage, build_register

LIMIT_FIELDS = tuple(f.name for f in fields(Limits))
"""The limit names, in the order alert, intervention, immediate (depth then loss)."""

MERGED_STATUSES = ("reference", "aligned")
"""Alignment states whose runs make the aggregate and the register."""


def load_limits(session: Session, track_id: int) -> tuple[Limits, TrackLimits | None]:
    """The track's limits and their stored row (None: the defaults apply)."""
    row = session.get(TrackLimits, track_id)
    if row is None:
        return Limits(), None
    return Limits(**{k: getattr(row, k) for k in LIMIT_FIELDS}), row


def save_limits(session: Session, track_id: int, limits: Limits) -> TrackLimits:
    """Store a track's limits (caller commits)."""
    row = session.get(TrackLimits, track_id)
    if row is None:
        row = TrackLimits(track_id=track_id)
        session.add(row)
    for k in LIMIT_FIELDS:
        setattr(row, k, getattr(limits, k))
    session.flush()
    return row


def track_observations(
    session: Session, track_id: int
) -> tuple[list[Observation], list[RunCoverage]]:
    """Every soft spot of the track's merged runs and every such run's extent (aligned, m)."""
    merged = (
        Run.track_id == track_id,
        Run.status == "done",
        Run.alignment_status.in_(MERGED_STATUSES),
    )
    runs = session.execute(
        select(Run.id, Run.recorded_at, Run.created_at, Run.chainage_offset_m,
               Run.chainage_min_m, Run.chainage_max_m).where(*merged)
    ).all()  # fmt: skip
    info: dict[int, tuple[datetime, float]] = {}
    coverage = []
    for rid, recorded, created, off, lo, hi in runs:
        at: datetime = recorded or created
        info[rid] = (at, off or 0.0)
        if lo is not None and hi is not None:
            coverage.append(RunCoverage(rid, at, lo + (off or 0.0), hi + (off or 0.0)))
    t = SoftSpot.__table__
    rows = session.execute(
        select(t.c.run_id, t.c.start_m, t.c.end_m, t.c.peak_m, t.c.depth_mm,
               t.c.stiffness_loss_pct)
        .join(Run, Run.id == t.c.run_id)
        .where(*merged)
    ).all()  # fmt: skip
    observations = []
    for rid, start, end, peak, depth, loss in rows:
        at, off = info[rid]
        observations.append(Observation(rid, at, start + off, end + off, peak + off, depth, loss))
    return observations, coverage


def track_register(session: Session, track_id: int, limits: Limits | None = None) -> list[Defect]:
    """The track's defects, most urgent first (see ``engine.register.build_register``)."""
    if limits is None:
        limits, _ = load_limits(session, track_id)
    observations, coverage = track_observations(session, track_id)
    return build_register(observations, coverage, limits=limits)
