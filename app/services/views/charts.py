"""Chart views for the dashboard: thinned profiles, the chainage map and the CSV preview.

A dashboard must never receive millions of points: a 100 km run has 400 000 grid points and a
track may carry fifty of them. These views answer what a chart of a given width can show:

- :func:`run_profile_view`: one run's profile in a window, min/max-thinned to ``max_points``
  (a dip survives any thinning);
- :func:`chainage_map`: every processed run of a track as a row of the chainage map, the soft
  spots of all of them (columnar), the zones they form across runs, and for windows up to
  :data:`HEATMAP_MAX_SPAN_M` the lowest level per run and chainage bin, computed by the
  database (GROUP BY over a range scan of the profile's primary key);
- :func:`track_window`: the fused profiles of all runs around one zone;
- :func:`truth_view`: a simulation's true level with the baseline detection measures from;
- :func:`csv_preview`: the engine's reading of the head of a log for the upload page.

Chainage is served aligned (stored chainage + :attr:`Run.offset_m`), levels in mm.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Iterable, Mapping, Sequence
from datetime import datetime

import numpy as np
from numpy.typing import NDArray
from sqlalchemy import func, select
from sqlalchemy.orm import Session

from app.db.models import Run, SoftSpot, Track
from app.schemas.simulate import TruthPublic
from app.schemas.views import (
    ChainageMapPublic,
    CsvPreviewPublic,
    HeatmapPublic,
    MapRunPublic,
    MapSpotsPublic,
    MapTrackPublic,
    ProfileViewPublic,
    WindowPublic,
    WindowRunPublic,
    ZonePublic,
)
from app.services.errors import Invalid
from app.services.run_lifecycle.simulation import Truth
from app.services.run_lifecycle.stored_runs import detail_run
from app.services.storage.profiles import nullable, profile_arrays
from app.services.storage.retention import require_detail
from app.services.track.register import LOAD_RATIO, separated_observations
from app.services.track.separation_trust import (
    TRUSTED,
    Trust,
    defects_trust,
    judge,
    run_bases,
)
from app.services.views.window import Window
from engine.chainage import GRID_STEP_M
from engine.decimate import minmax_indices
from engine.detect import DetectionConfig, robust_baseline
from engine.intervals import merge_intervals
from engine.logio import CsvOptions, preview_csv
from engine.register import Observation, RegisterConfig, RunCoverage, build_register

HEATMAP_MAX_SPAN_M = 10_000.0
"""Widest window given a heatmap, m. Wider windows (a whole 100 km line) show the soft spots
only: binning 50 runs x 400 000 points per request would not fit the 2 s budget (10 km of 50
runs, 2 million rows, take ~0.5 s), and at one bin per 80 m the lowest level of a bin says
little that the spots do not."""

HEATMAP_MIN_BIN_M = GRID_STEP_M
"""Narrowest heatmap bin, m (the profile grid step)."""


def _as_array(values: Sequence[float | None]) -> NDArray[np.float64]:
    return np.array([np.nan if v is None else v for v in values], dtype=np.float64)


def minmax_decimate(
    x: NDArray[np.float64], columns: dict[str, NDArray[np.float64]], max_points: int
) -> tuple[NDArray[np.float64], dict[str, NDArray[np.float64]], bool]:
    """Thin columns sharing one x axis to at most ``max_points`` points.

    The samples kept are :func:`engine.decimate.minmax_indices` over all columns (each keeps
    its own extremes; NaN buckets stay NaN).

    Returns
    -------
    x, columns, decimated
        The (possibly) thinned axis and columns, and whether anything was dropped.
    """
    if x.size <= max_points:
        return x, columns, False
    idx = minmax_indices(np.vstack(list(columns.values())), max_points)
    return x[idx], {k: v[idx] for k, v in columns.items()}, True


def _run_label(run: Run) -> str:
    # Built from the date and the numeric id only: never from user text, so a chart that
    # renders labels as markup cannot be fed any.
    if run.recorded_at is not None:
        return f"{run.recorded_at:%Y-%m-%d %H:%M} · run {run.id}"
    return f"run {run.id}"


def run_profile_view(
    session: Session, run_id: int, window: Window, max_points: int
) -> ProfileViewPublic:
    """A processed run's profile (fused, front, rear, baseline; mm) in a window, thinned to
    ``max_points`` for display."""
    run = detail_run(session, run_id, "profile")
    lo, hi = window.stored(run.offset_m)
    data = profile_arrays(session, run.id, lo, hi)
    require_detail(session, run, "profile")  # a sweep may have removed it meanwhile
    x = data["chainage_m"] + run.offset_m
    names = ("level_mm", "front_level_mm", "rear_level_mm", "baseline_mm")
    cols = {k: data[k] for k in names}
    xd, cd, decimated = minmax_decimate(x, cols, max_points)
    a, b = run.aligned_extent()
    from_m = window.from_m if window.from_m is not None else (a if a is not None else 0.0)
    to_m = window.to_m if window.to_m is not None else (b if b is not None else 0.0)
    if to_m < from_m:  # an open end filled from the run's extent, beyond the given one
        field = "to_m" if window.to_m is not None else "from_m"
        given = window.to_m if window.to_m is not None else window.from_m
        raise Invalid(
            f"the window ({field} {given:g} m) lies outside run {run.id}, which covers "
            f"{a:g} to {b:g} m of chainage",
            field=field,
        )
    return ProfileViewPublic(
        run_id=run.id,
        from_m=from_m,
        to_m=to_m,
        n_points=int(x.size),
        decimated=decimated,
        chainage_m=xd.tolist(),
        level_mm=nullable(cd["level_mm"]),
        front_level_mm=nullable(cd["front_level_mm"]),
        rear_level_mm=nullable(cd["rear_level_mm"]),
        baseline_mm=nullable(cd["baseline_mm"]),
    )


def truth_view(truth: Truth) -> TruthPublic:
    """What a simulation simulated, with the baseline of its true level as the detection
    draws it (:func:`engine.detect.robust_baseline`, the processing's window): the dashboard
    compares the truth and the recovered profile about their own baselines."""
    window_m = DetectionConfig().baseline_window_m
    x = np.asarray(truth.chainage_m, dtype=np.float64)
    step = float(x[1] - x[0]) if x.size > 1 else GRID_STEP_M
    baseline = robust_baseline(_as_array(truth.level_mm), step, window_m)
    return TruthPublic.model_validate(
        truth.to_dict() | {"baseline_mm": nullable(baseline), "baseline_window_m": window_m}
    )


def _map_runs(session: Session, track_id: int, max_runs: int) -> tuple[list[Run], int, int]:
    done = list(
        session.scalars(
            select(Run)
            .where(Run.track_id == track_id, Run.status == "done")
            .order_by(Run.recorded_at.desc().nulls_last(), Run.id.desc())
        )
    )
    pending = session.scalar(
        select(func.count()).select_from(Run).where(Run.track_id == track_id, Run.status != "done")
    )
    return done[:max_runs], max(0, len(done) - max_runs), int(pending or 0)


def _spots(
    session: Session, runs: list[Run], from_m: float | None, to_m: float | None
) -> MapSpotsPublic:
    index = {r.id: i for i, r in enumerate(runs)}
    offsets = {r.id: r.offset_m for r in runs}
    out = MapSpotsPublic(
        run_index=[], run_id=[], start_m=[], end_m=[], peak_m=[], depth_mm=[], stiffness_loss_pct=[]
    )
    if not runs:
        return out
    t = SoftSpot.__table__
    stmt = select(
        t.c.run_id, t.c.start_m, t.c.end_m, t.c.peak_m, t.c.depth_mm, t.c.stiffness_loss_pct
    ).where(t.c.run_id.in_(list(index)))
    # The runs' offsets differ: the statement keeps what any of them could place in the window
    # (a window of a long line reads its few spots, not every spot of the line).
    if from_m is not None:
        stmt = stmt.where(t.c.end_m >= from_m - max(offsets.values()))
    if to_m is not None:
        stmt = stmt.where(t.c.start_m <= to_m - min(offsets.values()))
    rows = session.execute(stmt.order_by(t.c.run_id, t.c.start_m)).all()
    for run_id, start, end, peak, depth, loss in rows:
        off = offsets[run_id]
        s, e = start + off, end + off
        if (from_m is not None and e < from_m) or (to_m is not None and s > to_m):
            continue
        out.run_index.append(index[run_id])
        out.run_id.append(run_id)
        out.start_m.append(s)
        out.end_m.append(e)
        out.peak_m.append(peak + off)
        out.depth_mm.append(depth)
        out.stiffness_loss_pct.append(loss)
    return out


def map_zones(
    spots: MapSpotsPublic,
    runs: list[Run],
    separated: Sequence[Observation] = (),
    of: Callable[[Iterable[tuple[str, int]]], Trust] | None = None,
) -> list[ZonePublic]:
    """The zones of the map: the register (:func:`engine.register.build_register`, the one
    zone model) over the soft spots shown, whatever the alignment state of their runs, and the
    track's separated soft spots (``separated``: the register's own sightings); a zone the
    separation found is provisional as ``of`` judges its passes
    (:func:`app.services.track.separation_trust.judge`; None: none is).

    A zone keeps the register's definitions: sightings overlapping or at most
    ``RegisterConfig.join_gap_m`` (1 m) apart join; one sighting per run (its deepest); the
    figures of the most trusted kind of evidence (the separation before single runs);
    ``runs_total`` counts the map runs covering it. Its extent is that of every sighting
    merged into it (a map shows where soft spots were seen; the register's median extent
    would hide a neighbouring dip it absorbed). ``severity`` ranks it for the map: the depth
    times the share of covering passes that support it.
    """
    by_id = {r.id: r for r in runs}
    observations = [
        Observation(
            run_id=rid,
            recorded_at=_when(by_id[rid]),
            start_m=a,
            end_m=b,
            peak_m=p,
            depth_mm=d,
            stiffness_loss_pct=loss,
        )
        for rid, a, b, p, d, loss in zip(
            spots.run_id, spots.start_m, spots.end_m, spots.peak_m, spots.depth_mm,
            spots.stiffness_loss_pct, strict=True,
        )
    ]  # fmt: skip
    observations += separated
    coverage = []
    for r in runs:
        lo, hi = r.aligned_extent()
        if lo is not None and hi is not None:
            coverage.append(RunCoverage(r.id, _when(r), lo, hi))
    defects = build_register(observations, coverage, config=RegisterConfig(load_ratio=LOAD_RATIO))
    # the register's clusters are merge_intervals groups: find each defect's by a member
    group_of: dict[int, int] = {}
    extents: list[tuple[float, float]] = []
    gap = RegisterConfig().join_gap_m
    starts = [o.start_m for o in observations]
    ends = [o.end_m for o in observations]
    for g in merge_intervals(starts, ends, gap):
        for i in g:
            group_of[id(observations[i])] = len(extents)
        extents.append((min(starts[i] for i in g), max(ends[i] for i in g)))
    spans = [extents[group_of[id(d.history[0])]] for d in defects]
    order = sorted(range(len(defects)), key=lambda k: spans[k][0])
    trust = defects_trust(defects, of) if of is not None else [TRUSTED] * len(defects)
    return [
        ZonePublic(
            id=n + 1,
            start_m=spans[k][0],
            end_m=spans[k][1],
            peak_m=d.peak_m,
            runs_seen=d.runs_seen,
            runs_total=d.runs_covering,
            depth_mm=d.depth_mm,
            depth_max_mm=max(o.depth_mm for o in d.history if o.source == d.source),
            stiffness_loss_pct=d.stiffness_loss_pct,
            severity=d.depth_mm * d.runs_seen / d.runs_covering,
            first_seen=d.first_seen,
            last_seen=d.last_seen,
            run_ids=sorted({p.id for o in d.history for p in o.passes if p.kind == "run"}),
            source=d.source,
            evidence_text=d.evidence_text,
            provisional=trust[k].provisional,
            provisional_reason=trust[k].reason,
        )
        for n, k in enumerate(order)
        for d in (defects[k],)
    ]


def _when(run: Run) -> datetime:
    when: datetime = run.recorded_at or run.created_at
    return when


def _heatmap(
    session: Session, runs: list[Run], from_m: float, to_m: float, bins: int
) -> HeatmapPublic:
    """Lowest fused level per run and chainage bin (runs without detail: empty rows)."""
    width = max((to_m - from_m) / bins, HEATMAP_MIN_BIN_M)
    nbins = max(1, math.ceil((to_m - from_m) / width))
    z: list[list[float | None]] = []
    for run in runs:
        off = run.offset_m
        lo, hi = from_m - off, to_m - off
        cols = profile_arrays(session, run.id, lo, hi, ("chainage_m", "level_mm"))
        x, level = cols["chainage_m"], cols["level_mm"]
        keep = (x < hi) & np.isfinite(level)
        b = np.floor((x[keep] - lo) / width).astype(np.int64)
        inside = (b >= 0) & (b < nbins)
        low = np.full(nbins, np.inf)
        np.minimum.at(low, b[inside], level[keep][inside])
        row: list[float | None] = np.round(low, 4).tolist()
        for i in np.flatnonzero(~np.isfinite(low)).tolist():
            row[i] = None
        z.append(row)
    x = (from_m + (np.arange(nbins) + 0.5) * width).tolist()
    return HeatmapPublic(x=x, bin_m=width, z=z)


def chainage_map(
    session: Session,
    track: Track,
    window: Window,
    *,
    bins: int,
    spots: bool,
    zones: bool,
    heatmap: bool,
    max_runs: int,
) -> ChainageMapPublic:
    """The chainage map of a track: runs x chainage, soft spots, zones, and the heatmap (lowest
    level per run and bin) for windows up to :data:`HEATMAP_MAX_SPAN_M`; without a window the
    whole extent of the track's runs."""
    runs, omitted, pending = _map_runs(session, track.id, max_runs)
    extents = [r.aligned_extent() for r in runs]
    los = [lo for lo, _ in extents if lo is not None]
    his = [hi for _, hi in extents if hi is not None]
    cmin = min(los) if los else None
    cmax = max(his) if his else None

    spot_cols = _spots(session, runs, window.from_m, window.to_m) if spots else None
    counts: dict[int, int] = {}
    if spot_cols is not None:
        for rid in spot_cols.run_id:
            counts[rid] = counts.get(rid, 0) + 1
    map_runs = [
        MapRunPublic(
            id=r.id,
            label=_run_label(r),
            name=r.name,
            recorded_at=r.recorded_at,
            vehicle=r.vehicle.name,
            chainage_min_m=lo,
            chainage_max_m=hi,
            chainage_offset_m=r.offset_m,
            n_soft_spots=counts.get(r.id, r.n_soft_spots or 0)
            if spot_cols is not None
            else (r.n_soft_spots or 0),
        )
        for r, (lo, hi) in zip(runs, extents, strict=True)
    ]
    heat: HeatmapPublic | None = None
    note: str | None = None
    a = window.from_m if window.from_m is not None else cmin
    b = window.to_m if window.to_m is not None else cmax
    if heatmap and runs and a is not None and b is not None and b > a:
        if b - a <= HEATMAP_MAX_SPAN_M:
            heat = _heatmap(session, runs, a, b, bins)
        else:
            note = (
                f"the level heatmap is drawn for windows up to {HEATMAP_MAX_SPAN_M / 1000:g} km; "
                f"this one is {(b - a) / 1000:.1f} km (zoom in)"
            )
    return ChainageMapPublic(
        track=MapTrackPublic.model_validate(
            {k: getattr(track, k) for k in MapTrackPublic.model_fields}
        ),
        chainage_min_m=cmin,
        chainage_max_m=cmax,
        from_m=window.from_m,
        to_m=window.to_m,
        runs=map_runs,
        runs_omitted=omitted,
        runs_pending=pending,
        spots=spot_cols,
        zones=_zones(session, track.id, spot_cols, runs, window)
        if spot_cols is not None and zones
        else None,
        heatmap=heat,
        heatmap_note=note,
    )


def _zones(
    session: Session, track_id: int, spots: MapSpotsPublic, runs: list[Run], window: Window
) -> list[ZonePublic]:
    """The map's zones (:func:`map_zones`) with the track's separated soft spots in the
    window, each judged provisional or not."""
    separated = _separated_in(session, track_id, window)
    of = judge(run_bases(session, track_id)) if separated else None
    return map_zones(spots, runs, separated, of)


def _separated_in(session: Session, track_id: int, window: Window) -> list[Observation]:
    """The track's separated soft spots overlapping the window, as register sightings."""
    return [
        o
        for o in separated_observations(session, track_id)
        if (window.from_m is None or o.end_m >= window.from_m)
        and (window.to_m is None or o.start_m <= window.to_m)
    ]


def track_window(
    session: Session, track: Track, window: Window, *, max_points: int, max_runs: int
) -> WindowPublic:
    """The fused profile of every processed run covering part of a closed window (at most
    :data:`HEATMAP_MAX_SPAN_M` wide), oldest run first, each thinned to ``max_points``."""
    from_m, to_m, span = window.from_m, window.to_m, window.span_m
    if from_m is None or to_m is None or span is None:
        raise Invalid(
            "from_m and to_m are both needed", field="from_m" if from_m is None else "to_m"
        )
    if span > HEATMAP_MAX_SPAN_M:
        raise Invalid(
            f"the window is {span / 1000:.1f} km; at most "
            f"{HEATMAP_MAX_SPAN_M / 1000:g} km of every run's profile are served at once",
            field="to_m",
        )
    runs, _, _ = _map_runs(session, track.id, max_runs)
    out: list[WindowRunPublic] = []
    for run in reversed(runs):  # oldest first: later runs draw on top
        lo, hi = run.aligned_extent()
        if lo is None or hi is None or hi < from_m or lo > to_m:
            continue
        a, b = window.stored(run.offset_m)
        data = profile_arrays(session, run.id, a, b, ("chainage_m", "level_mm"))
        if not data["chainage_m"].size:
            continue
        x = data["chainage_m"] + run.offset_m
        level = data["level_mm"]
        xd, cd, decimated = minmax_decimate(x, {"level_mm": level}, max_points)
        out.append(
            WindowRunPublic(
                id=run.id,
                label=_run_label(run),
                recorded_at=run.recorded_at,
                wheel_load_n=run.mean_wheel_force_n or run.static_wheel_load_n,
                vehicle=run.vehicle.name,
                decimated=decimated,
                chainage_m=xd.tolist(),
                level_mm=nullable(cd["level_mm"]),
            )
        )
    return WindowPublic(from_m=from_m, to_m=to_m, runs=out)


PREVIEW_MAX_BYTES = 256 * 1024
"""Largest head of a file the CSV preview reads, bytes."""

PREVIEW_OPTION_NAMES = tuple(f.name for f in dataclasses.fields(CsvOptions))
"""Form fields of the preview: the upload's column/unit options (blank = recognise), taken
from :class:`engine.logio.CsvOptions` so the two cannot drift."""


def csv_preview(data: bytes, n_rows: int, chosen: Mapping[str, str]) -> CsvPreviewPublic:
    """How the engine would read the head of a log with the options ``chosen`` (the
    :class:`engine.logio.CsvOptions` fields set; the others are recognised). Nothing is
    stored; problems of the content are ``warnings``; an empty file is :class:`Invalid`."""
    if not data:
        raise Invalid("the file is empty", field="file")
    preview = preview_csv(data[:PREVIEW_MAX_BYTES], n_rows=n_rows, options=CsvOptions(**chosen))
    return CsvPreviewPublic(
        columns=list(preview.columns),
        rows=[list(r) for r in preview.rows],
        delimiter=preview.delimiter,
        mapping=dict(preview.mapping),
        units=dict(preview.units),
        gravity=preview.gravity,
        warnings=list(preview.warnings),
        recorded_at=preview.recorded_at,
    )
