"""A track's soft-spot register and its limits.

The register is built on request (``engine.register.build_register``) from the stored soft
spots of the track's merged runs (reference or aligned; every processed run when none is
merged), shifted by each run's offset, and from the track's separated soft spots with the
passes behind them; each run's aligned extent is its coverage and its recording time (upload
time when unknown) the time of its sightings. Limits are stored per track; a track without
its own uses the engine's defaults.
"""

from __future__ import annotations

import bisect
import dataclasses
import math
from collections.abc import Mapping, Sequence
from dataclasses import fields
from datetime import datetime
from typing import Any

from sqlalchemy import ColumnElement, func, select
from sqlalchemy.orm import Session

from app.db.models import Run, SoftSpot, Survey, TrackLimits, TrackStiffnessSpot
from app.services.track.aggregate import read_combined_spots
from app.services.track.alignment import MERGED_STATUSES
from app.services.track.quality_register import isolated_register
from app.services.track.separation_history import pass_key, read_history
from app.services.track.separation_store import NOT_SEPARABLE, separable_intervals, spot_support
from app.services.track.separation_trust import TRUSTED, Trust, defects_trust, judge, run_bases
from engine.register import (
    Defect,
    Limits,
    Observation,
    RegisterConfig,
    RunCoverage,
    Support,
    build_register,
    complete_at,
)
from engine.separation import SeparationConfig

LOAD_RATIO = SeparationConfig().min_load_ratio
"""Wheel loads this ratio apart count as distinct: the separation's own threshold."""

LIMIT_FIELDS = tuple(f.name for f in fields(Limits))
"""The limit names, in the order alert, intervention, immediate (depth then loss)."""


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
    """Every sighting on the track and every merged run's extent (aligned, m).

    The sightings are the soft spots of the track's merged runs, one run each (``pass``), and
    the separated soft spots (``separated``), each with the passes behind it and their wheel
    loads. A track none of whose runs is merged (all stored before alignment existed, or none
    could be aligned) uses every processed run at its own chainage: the register is the one
    zone model, aligned or not.
    """
    done = (Run.track_id == track_id, Run.status == "done")
    merged: tuple[ColumnElement[bool], ...] = (*done, Run.alignment_status.in_(MERGED_STATUSES))
    if session.scalar(select(Run.id).where(*merged).limit(1)) is None:
        merged = done
    runs = session.execute(
        select(Run.id, Run.recorded_at, Run.created_at, Run.chainage_offset_m,
               Run.chainage_min_m, Run.chainage_max_m,
               func.coalesce(Run.mean_wheel_force_n, Run.static_wheel_load_n)).where(*merged)
    ).all()  # fmt: skip
    info: dict[int, tuple[datetime, float]] = {}
    passes: dict[tuple[str, int], Support] = {}
    coverage = []
    for rid, recorded, created, off, lo, hi, load in runs:
        at: datetime = recorded or created
        info[rid] = (at, off or 0.0)
        passes["run", rid] = Support(rid, at, load)
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
        observations.append(
            Observation(rid, at, start + off, end + off, peak + off, depth, loss,
                        support=(passes["run", rid],))
        )  # fmt: skip
    observations = with_aggregate_sightings(session, track_id, observations, coverage, passes)
    observations += separated_observations(session, track_id, passes)
    return observations, coverage


def with_aggregate_sightings(
    session: Session,
    track_id: int,
    observations: list[Observation],
    coverage: list[RunCoverage],
    passes: dict[tuple[str, int], Support],
) -> list[Observation]:
    """The runs' dips plus what the combined passes show (``engine.accumulate``).

    The track's runs are combined per stretch (their aligned levels, weighted by each one's
    measured noise) and the soft spots of the combination are found against its own measured
    noise when a run is integrated (``app.services.track.aggregate.read_combined_spots``): many MEMS
    passes see what none of them sees alone. A combined spot is evidence from the passes that
    support it (cover it and dip there themselves): each such merged run that did not report
    a dip there gets an observation of the combined spot; a run's own dip there without a
    stiffness-loss figure takes the combined one. Only stretches with at least two runs are
    combined.
    """
    when = {c.run_id: c.recorded_at for c in coverage}
    out = list(observations)
    by_run: dict[int, list[int]] = {}
    for i, o in enumerate(out):
        by_run.setdefault(o.run_id, []).append(i)
    for spot in read_combined_spots(session, track_id):
        loss = spot.loss_pct
        for rid in spot.supporting:
            if rid not in when:
                continue
            own = [
                i for i in by_run.get(rid, [])
                if out[i].start_m <= spot.end_m and out[i].end_m >= spot.start_m
            ]  # fmt: skip
            for i in own:
                v = out[i].stiffness_loss_pct
                if loss is not None and (v is None or not math.isfinite(v)):
                    out[i] = dataclasses.replace(out[i], stiffness_loss_pct=loss)
            if not own:
                out.append(Observation(rid, when[rid], spot.start_m, spot.end_m, spot.peak_m,
                                       spot.depth_mm, loss, support=_one(passes, rid)))  # fmt: skip
    return out


def _one(passes: dict[tuple[str, int], Support], rid: int) -> tuple[Support, ...]:
    support = passes.get(("run", rid))
    return (support,) if support is not None else ()


def run_supports(session: Session, track_id: int) -> dict[tuple[str, int], Support]:
    """Every processed run of the track as a pass: recording time (else upload) and load."""
    rows = session.execute(
        select(Run.id, Run.recorded_at, Run.created_at,
               func.coalesce(Run.mean_wheel_force_n, Run.static_wheel_load_n))
        .where(Run.track_id == track_id, Run.status == "done")
    ).all()  # fmt: skip
    return {("run", rid): Support(rid, rec or cre, load) for rid, rec, cre, load in rows}


def separated_observations(
    session: Session, track_id: int, passes: dict[tuple[str, int], Support] | None = None
) -> list[Observation]:
    """The track's separated soft spots as sightings, each supported by the passes with data
    over it (``track_stiffness_spots.support``; for a spot stored before that was kept, the
    passes of its chunk). Depth is the dip the softened support causes under the separation's
    reference wheel load; the sighting dates from when its passes first spanned two loads."""
    spots = session.scalars(
        select(TrackStiffnessSpot)
        .where(TrackStiffnessSpot.track_id == track_id)
        .order_by(TrackStiffnessSpot.start_m)
    ).all()
    if not spots:
        return []
    passes = dict(run_supports(session, track_id) if passes is None else passes)
    for sid, recorded, created, load in session.execute(
        select(Survey.id, Survey.recorded_at, Survey.created_at, Survey.wheel_load_n).where(
            Survey.track_id == track_id
        )
    ):
        passes["survey", sid] = Support(sid, recorded or created, load, kind="survey")
    history = read_history(session, track_id)
    made: dict[tuple[str, int, Any], Support] = {}
    out = []
    for spot in spots:
        support = _supports(
            spot_support(session, spot),
            passes,
            made,
        )
        if not support:
            continue
        # the spot's earlier separations, each dated from the pass that completed its new
        # evidence; the current one is the latest entry's (or, before any history, the
        # spot's own passes)
        entries = history.of(spot.start_m, spot.end_m)
        at = complete_at(support, LOAD_RATIO)
        seen = frozenset[tuple[str, int]]()
        for i, e in enumerate(entries):
            added = _supports([x for x in e.support if pass_key(x) not in seen], passes, made)
            seen = e.base
            if added:
                t = complete_at(added, LOAD_RATIO)
                at = t if i == 0 else max(at, t)
            was = _supports(e.support, passes, made)
            if i == len(entries) - 1 or len(was) < len(e.support):
                continue  # the latest is the current spot; one with a deleted pass is void
            out.append(_separated(was, at, e))
        out.append(_separated(support, at, spot))
    return out


def _supports(
    entries: Sequence[Mapping[str, Any]],
    passes: Mapping[tuple[str, int], Support],
    made: dict[tuple[str, int, Any], Support],
) -> tuple[Support, ...]:
    """The stored passes of support entries (``{"kind", "id", "force_n"}``), each with its
    wheel load over the spot; passes no longer stored are left out. ``made`` keeps each pass
    at each load once (a long line's history names the same passes thousands of times)."""
    out = []
    for e in entries:
        key = pass_key(e)
        if key not in passes:
            continue
        force = e.get("force_n")
        support = made.get((*key, force))
        if support is None:
            support = made[(*key, force)] = dataclasses.replace(passes[key], wheel_load_n=force)
        out.append(support)
    return tuple(out)


def _separated(support: tuple[Support, ...], at: datetime, spot: Any) -> Observation:
    """A separated soft spot (``TrackStiffnessSpot`` or a history ``Entry``) as a sighting."""
    runs = sorted((p for p in support if p.kind == "run"), key=lambda p: (p.recorded_at, p.id))
    return Observation(
        runs[0].id if runs else 0, at, spot.start_m, spot.end_m, spot.peak_m,
        spot.depth_mm or 0.0, spot.loss_pct, source="separated", support=support,
        loss_lo_pct=spot.loss_lo_pct, loss_hi_pct=spot.loss_hi_pct,
    )  # fmt: skip


def track_register(session: Session, track_id: int, limits: Limits | None = None) -> list[Defect]:
    """The track's defects, most urgent first (see ``engine.register.build_register``)."""
    if limits is None:
        limits, _ = load_limits(session, track_id)
    observations, coverage = track_observations(session, track_id)
    config = RegisterConfig(load_ratio=LOAD_RATIO)
    defects = build_register(observations, coverage, limits=limits, config=config)
    # isolated level defects are a register of their own limits, kept apart from soft spots
    defects += isolated_register(session, track_id, coverage, config)
    defects.sort(key=lambda d: (d.priority, -d.depth_mm, d.start_m))
    return defects


def stiffness_notes(
    session: Session, track_id: int, defects: Sequence[Defect]
) -> list[tuple[str | None, str | None]]:
    """What each defect's stiffness loss rests on, and the message where there is none.

    ``("separated", None)`` for a defect the separation found, ``("single pass", None)`` for
    a loss from runs over smooth rail, ``(None, None)`` for a dip by depth only inside a
    stretch where the separation holds (it found no soft support there: geometry), and
    ``(None, NOT_SEPARABLE)`` for a dip listed by depth only because one load cannot tell.
    """
    intervals = separable_intervals(session, track_id)
    starts = [a for a, _ in intervals]

    def separable(d: Defect) -> bool:
        # the stretches are ordered and disjoint: only the last one starting at or before the
        # defect can hold it
        i = bisect.bisect_right(starts, d.start_m) - 1
        return i >= 0 and intervals[i][1] >= d.end_m

    out: list[tuple[str | None, str | None]] = []
    for d in defects:
        if d.source == "separated":
            out.append(("separated", None))
        elif d.source == "isolated":
            out.append((None, None))  # a level defect: no stiffness is claimed
        elif d.stiffness_loss_pct is not None:
            out.append(("single pass", None))
        elif separable(d):
            out.append((None, None))
        else:
            out.append((None, NOT_SEPARABLE))
    return out


def provisional_notes(session: Session, track_id: int, defects: Sequence[Defect]) -> list[Trust]:
    """Whether each defect is provisional (see :mod:`app.services.track.separation_trust`):
    a defect the separation found, judged by the passes of its current separation; any
    other is not."""
    if not any(d.source == "separated" for d in defects):
        return [TRUSTED] * len(defects)
    return defects_trust(defects, judge(run_bases(session, track_id)))
