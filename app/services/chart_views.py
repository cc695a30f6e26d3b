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
- :func:`csv_preview`: the engine's reading of the head of a log for the upload page.

Chainage is served aligned (stored chainage + :attr:`Run.offset_m`), levels in mm.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from datetime import datetime

import numpy as np
from numpy.typing import NDArray
from sqlalchemy import Float, Integer, and_, cast, func, select
from sqlalchemy.orm import Session

from app.db.models import ProfilePoint, Run, SoftSpot, Track
from app.schemas.views import (
    ChainageMapPublic,
    CsvPreviewPublic,
    HeatmapPublic,
    MapRunPublic,
    MapSpotsPublic,
    ProfileViewPublic,
    WindowPublic,
    WindowRunPublic,
    ZonePublic,
)
from engine.chainage import GRID_STEP_M
from engine.decimate import minmax_indices
from engine.intervals import merge_intervals
from engine.logio import CsvOptions, preview_csv

from .errors import Invalid
from .profiles import read_profile
from .runs import done_run
from .window import Window

HEATMAP_MAX_SPAN_M = 10_000.0
"""Widest window given a heatmap, m. Wider windows (a whole 100 km line) show the soft spots
only: binning 50 runs x 400 000 points per request would not fit the 2 s budget (10 km of 50
runs, 2 million rows, take ~0.5 s), and at one bin per 80 m the lowest level of a bin says
little that the spots do not."""

HEATMAP_MIN_BIN_M = GRID_STEP_M
"""Narrowest heatmap bin, m (the profile grid step)."""

ZONE_GAP_M = 2.0
"""Soft spots of different runs closer than this (or overlapping) form one zone, m."""


def _finite_or_none(values: NDArray[np.float64]) -> list[float | None]:
    out: list[float | None] = values.tolist()
    for i in np.flatnonzero(~np.isfinite(values)):
        out[i] = None
    return out


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
    run = done_run(session, run_id, "profile")
    lo, hi = window.stored(run.offset_m)
    data = read_profile(session, run.id, lo, hi)
    x = np.asarray(data["chainage_m"], dtype=np.float64) + run.offset_m
    names = ("level_mm", "front_level_mm", "rear_level_mm", "baseline_mm")
    cols = {k: _as_array(data[k]) for k in names}
    xd, cd, decimated = minmax_decimate(x, cols, max_points)
    a, b = run.aligned_extent()
    return ProfileViewPublic(
        run_id=run.id,
        from_m=window.from_m if window.from_m is not None else (a if a is not None else 0.0),
        to_m=window.to_m if window.to_m is not None else (b if b is not None else 0.0),
        n_points=int(x.size),
        decimated=decimated,
        chainage_m=xd.tolist(),
        level_mm=_finite_or_none(cd["level_mm"]),
        front_level_mm=_finite_or_none(cd["front_level_mm"]),
        rear_level_mm=_finite_or_none(cd["rear_level_mm"]),
        baseline_mm=_finite_or_none(cd["baseline_mm"]),
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


def cluster_zones(
    spots: MapSpotsPublic, runs: list[Run], gap_m: float = ZONE_GAP_M
) -> list[ZonePublic]:
    """Merge the soft spots of all runs into zones: spots overlapping or closer than ``gap_m``.

    A zone's depth and stiffness loss are medians over the runs that saw it (a run seeing two
    spots in one zone counts once, with its deepest); its severity is that depth times the
    share of the runs covering the zone that detected it, so a dip seen once in fifty passes
    ranks below one seen every time.
    """
    n = len(spots.start_m)
    if n == 0:
        return []
    groups = [g.tolist() for g in merge_intervals(spots.start_m, spots.end_m, gap_m)]
    extents = [r.aligned_extent() for r in runs]
    zones: list[ZonePublic] = []
    for k, members in enumerate(groups):
        deepest: dict[int, int] = {}
        for i in members:
            ri = spots.run_index[i]
            if ri not in deepest or spots.depth_mm[i] > spots.depth_mm[deepest[ri]]:
                deepest[ri] = i
        picked = list(deepest.values())
        start = min(spots.start_m[i] for i in members)
        stop = max(spots.end_m[i] for i in members)
        depths = [spots.depth_mm[i] for i in picked]
        losses = [spots.stiffness_loss_pct[i] for i in picked]
        losses_known = [v for v in losses if v is not None]
        covering = sum(
            1
            for lo, hi in extents
            if lo is not None and hi is not None and lo <= start and hi >= stop
        )
        runs_total = max(covering, len(deepest))
        dates = [
            runs[ri].recorded_at or runs[ri].created_at for ri in deepest if runs[ri] is not None
        ]
        dates_known: list[datetime] = [d for d in dates if d is not None]
        depth = float(np.median(depths))
        zones.append(
            ZonePublic(
                id=k + 1,
                start_m=start,
                end_m=stop,
                peak_m=float(np.median([spots.peak_m[i] for i in picked])),
                runs_seen=len(deepest),
                runs_total=runs_total,
                depth_mm=depth,
                depth_max_mm=float(max(depths)),
                stiffness_loss_pct=float(np.median(losses_known)) if losses_known else None,
                severity=depth * len(deepest) / runs_total,
                first_seen=min(dates_known) if dates_known else None,
                last_seen=max(dates_known) if dates_known else None,
                run_ids=sorted(runs[ri].id for ri in deepest),
            )
        )
    return zones


def _heatmap(
    session: Session, runs: list[Run], from_m: float, to_m: float, bins: int
) -> HeatmapPublic:
    """Lowest fused level per run and chainage bin, binned by the database."""
    width = max((to_m - from_m) / bins, HEATMAP_MIN_BIN_M)
    nbins = max(1, math.ceil((to_m - from_m) / width))
    t = ProfilePoint.__table__
    dialect = session.get_bind().dialect.name
    z: list[list[float | None]] = []
    for run in runs:
        off = run.offset_m
        lo, hi = from_m - off, to_m - off
        # Bin index of each row; the WHERE keeps the argument >= 0, where SQLite's integer
        # CAST (truncation) is a floor. Other databases round on CAST, so they floor first.
        arg = (t.c.chainage_m - lo) / width
        bin_expr = cast(arg, Integer) if dialect == "sqlite" else cast(func.floor(arg), Integer)
        stmt = (
            select(bin_expr.label("b"), cast(func.min(t.c.level_mm), Float))
            .where(
                and_(
                    t.c.run_id == run.id,
                    t.c.chainage_m >= lo,
                    t.c.chainage_m < hi,
                    t.c.level_mm.is_not(None),
                )
            )
            .group_by("b")
        )
        row: list[float | None] = [None] * nbins
        for b, level in session.execute(stmt):
            if b is not None and 0 <= int(b) < nbins and level is not None:
                row[int(b)] = round(float(level), 4)
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
        track={
            "id": track.id,
            "name": track.name,
            "description": track.description,
            "rail": track.rail,
            "k_nominal": track.k_nominal,
            "spacing": track.spacing,
        },
        chainage_min_m=cmin,
        chainage_max_m=cmax,
        from_m=window.from_m,
        to_m=window.to_m,
        runs=map_runs,
        runs_omitted=omitted,
        runs_pending=pending,
        spots=spot_cols,
        zones=cluster_zones(spot_cols, runs) if spot_cols is not None and zones else None,
        heatmap=heat,
        heatmap_note=note,
    )


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
        data = read_profile(session, run.id, a, b, ("chainage_m", "level_mm"))
        if not data["chainage_m"]:
            continue
        x = np.asarray(data["chainage_m"], dtype=np.float64) + run.offset_m
        level = _as_array(data["level_mm"])
        xd, cd, decimated = minmax_decimate(x, {"level_mm": level}, max_points)
        out.append(
            WindowRunPublic(
                id=run.id,
                label=_run_label(run),
                recorded_at=run.recorded_at,
                decimated=decimated,
                chainage_m=xd.tolist(),
                level_mm=_finite_or_none(cd["level_mm"]),
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
    )
