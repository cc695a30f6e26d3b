"""A track's geometry quality in EN 13848 terms: D1/D2 level, section SDs and classes,
isolated defects against speed-class limits, repeatability, trends, survey comparison, GeoJSON.

The level analysed is the track's unloaded geometry where the two-load separation holds
(``app.services.track.separation_store``), else the aggregated loaded level
(``app.services.track.aggregate``),
point by point; each section says which (``basis``: ``unloaded``, ``loaded`` or ``mixed``).
Passes are each chunk's newest aligned runs (``aggregate.newest_runs``). Everything is
computed on read from stored arrays, over the window asked for plus a chunk of context either
side: the numerics take 0.45 s for 10 km and 20 passes (docs/benchmarks.md).

Units: chainage m (aligned), levels mm, speeds km/h, time UTC.
"""

from __future__ import annotations

import dataclasses
import math
from collections import defaultdict
from collections.abc import Iterator
from dataclasses import dataclass
from datetime import datetime
from typing import Any, cast

import numpy as np
from numpy.typing import NDArray
from sqlalchemy import delete, select
from sqlalchemy.orm import Session

from app.db.base import utcnow
from app.db.models import (
    Run,
    Survey,
    SurveyLevels,
    Track,
    TrackLineSpeed,
    TrackQualityLimits,
    TrackRunLevels,
    Vehicle,
)
from app.services.errors import Invalid
from app.services.storage.packing import unpack_f4
from app.services.storage.profiles import unpack_long_level
from app.services.track.aggregate import (
    CHUNK_POINTS,
    aggregate_chunk_range,
    newest_runs,
    read_aggregate,
    unchunked_by_run,
)
from app.services.track.alignment import GRID_STEP_M
from app.services.track.separation_store import read_stiffness
from app.services.views.window import Window
from engine.aggregate import column_nanmedian
from engine.errors import ParameterError
from engine.pipeline import ProcessConfig
from engine.quality_limits import (
    DEFAULTS_SOURCE,
    LEVELS,
    IsolatedDefect,
    LineSpeed,
    QualityLimits,
    check_line_speeds,
    isolated_defects,
    next_limit,
    speed_at,
    speed_class,
    unverified_defaults,
)
from engine.track_quality import (
    BAND_LEVEL,
    BANDS,
    END_TRIM_M,
    LONG_LEVEL_LAMBDA_MAX_M,
    BandFilter,
    band_levels,
    observability,
    predict_crossing,
    repeatability,
    section_statistics,
    trim_ends,
)
from engine.vehicle_kinds import vehicle_from_dict

PRODUCT_BAND_MAX_M = ProcessConfig().lambda_max_m
"""Longest wavelength the stored levels hold (m): D2 beyond it is missing from the answer."""

REPEATABILITY_BAND = BandFilter("6-70 m", 6.0, 70.0)
"""Band of the repeatability figure EN 13848-2 asks of a measuring system (lambda >= 6 m)."""

PEAK_MATCH_M = 2.0
"""A pass's value of a defect is its largest |level| within this distance of the peak, m."""

MIN_SECTION_COVERAGE = 0.5
"""Least share of a section a pass must cover to count as a pass over it."""


# ----------------------------------------------------------------------- settings (stored)


def load_quality_limits(session: Session, track_id: int) -> tuple[QualityLimits, datetime | None]:
    """The track's quality limits and when they were set (None: the defaults)."""
    row = session.get(TrackQualityLimits, track_id)
    if row is None:
        return QualityLimits(), None
    return QualityLimits.from_dict(row.data), row.updated_at


def save_quality_limits(session: Session, track_id: int, data: dict[str, Any]) -> QualityLimits:
    """Check and store a track's quality limits (keys left out take defaults; caller commits)."""
    try:
        limits = QualityLimits.from_dict(data)
    except (ParameterError, TypeError, ValueError) as exc:
        field = getattr(exc, "field", None) or "body"
        raise Invalid(f"quality limits: {exc}", field=field) from None
    row = session.get(TrackQualityLimits, track_id)
    if row is None:
        row = TrackQualityLimits(track_id=track_id, data=limits.to_dict())
        session.add(row)
    else:
        row.data = limits.to_dict()
    session.flush()
    return limits


def load_line_speeds(session: Session, track_id: int) -> tuple[LineSpeed, ...]:
    """The track's line speeds by chainage, ordered."""
    rows = session.scalars(
        select(TrackLineSpeed)
        .where(TrackLineSpeed.track_id == track_id)
        .order_by(TrackLineSpeed.from_m)
    ).all()
    return tuple(LineSpeed(r.from_m, r.to_m, r.speed_kmh) for r in rows)


def save_line_speeds(
    session: Session, track_id: int, ranges: list[tuple[float, float, float]]
) -> tuple[LineSpeed, ...]:
    """Replace the track's line speeds (``(from_m, to_m, speed_kmh)`` each); Invalid naming the
    range (``field`` ``ranges[i].to_m`` ...) when one is wrong or two overlap. Caller commits."""
    speeds = []
    for i, (a, b, v) in enumerate(ranges):
        try:
            speeds.append(LineSpeed(float(a), float(b), float(v)))
        except ParameterError as exc:
            raise Invalid(f"ranges[{i}]: {exc}", field=f"ranges[{i}].{exc.field}") from None
    try:
        ordered = check_line_speeds(speeds)
    except ParameterError as exc:
        raise Invalid(str(exc), field="ranges") from None
    session.execute(delete(TrackLineSpeed).where(TrackLineSpeed.track_id == track_id))
    session.add_all(
        TrackLineSpeed(track_id=track_id, from_m=s.from_m, to_m=s.to_m, speed_kmh=s.speed_kmh)
        for s in ordered
    )
    session.flush()
    return ordered


# ------------------------------------------------------------------------------- reading


@dataclass(frozen=True)
class _Levels:
    """The track's analysed level on its grid, with its basis and the passes over it.

    ``long_mm`` is the passes' median long level (D2's own: ``engine.track_quality.long_level``,
    NaN where no pass kept one), ``long_passes`` each pass's (empty until :func:`with_passes`);
    ``long_pending`` the passes whose long level is still being inverted (answered done before
    it: ``Run.long_level_pending``), left out of both. The passes are float32 (as stored): a
    whole track's passes are in memory at once.
    """

    i0: int
    level_mm: NDArray[np.float64]
    unloaded: NDArray[np.bool_]
    passes: dict[int, NDArray[np.float32]]
    recorded: dict[int, datetime | None]
    vehicle_speeds: dict[int, list[float]]
    long_mm: NDArray[np.float64] | None = None
    long_passes: dict[int, NDArray[np.float32]] = dataclasses.field(default_factory=dict)
    long_pending: frozenset[int] = frozenset()

    @property
    def ordered_runs(self) -> list[int]:
        """The passes' run ids in recording order (then id)."""
        return sorted(self.passes, key=lambda r: (self.recorded.get(r) or utcnow(), r))

    @property
    def chainage_m(self) -> NDArray[np.float64]:
        return (self.i0 + np.arange(self.level_mm.size, dtype=np.float64)) * GRID_STEP_M


def read_levels(
    session: Session, track_id: int, window: Window, *, passes: bool = True
) -> _Levels | None:
    """The analysed level over ``window`` plus a chunk either side, and (``passes``) the passes
    over it (else none: :func:`with_passes` adds them)."""
    stored = aggregate_chunk_range(session, track_id)
    if stored is None:
        return None
    c_lo, c_hi = stored
    # the window plus a chunk of context either side: the filters' reach (1.5 x 70 m)
    if window.from_m is not None:
        c_lo = max(c_lo, math.floor(window.from_m / GRID_STEP_M) // CHUNK_POINTS - 1)
    if window.to_m is not None:
        c_hi = min(c_hi, math.floor(window.to_m / GRID_STEP_M) // CHUNK_POINTS + 1)
    if c_hi < c_lo:
        return None
    i0, i1 = c_lo * CHUNK_POINTS, (c_hi + 1) * CHUNK_POINTS - 1
    n = i1 - i0 + 1
    span = read_aggregate(session, track_id, i0, i1)
    level = np.where(span.n_runs > 0, span.level_mm, np.nan)
    sep = read_stiffness(session, track_id, i0 * GRID_STEP_M, i1 * GRID_STEP_M)
    unloaded = np.zeros(n, dtype=bool)
    if sep.n:
        idx = np.rint(np.asarray(sep.columns["chainage_m"]) / GRID_STEP_M).astype(np.int64) - i0
        geo = np.array([np.nan if v is None else v for v in sep.columns["geometry_mm"]])
        ok = (idx >= 0) & (idx < n) & np.isfinite(geo) & np.asarray(sep.columns["separable"])
        level[idx[ok]] = geo[ok]
        unloaded[idx[ok]] = True
    lv = _Levels(i0, level, unloaded, {}, {}, {})
    if passes:
        return with_passes(session, track_id, lv)
    # D2's own level even without the passes: a screen for defects sees the D2 they will
    rows = _pass_rows(session, track_id, lv, TrackRunLevels.__table__.c.long_mm)
    longs = _spread(((r, c, b) for r, c, b, _ in rows), lv, unpack_long_level)
    return dataclasses.replace(
        lv, long_mm=_median(list(longs.values()), n),
        long_pending=_pending_long(session, {int(r[0]) for r in rows if r[3]}),
    )  # fmt: skip


def _pass_rows(session: Session, track_id: int, lv: _Levels, *columns: Any) -> list[Any]:
    """The stored rows ``(run id, chunk, *columns, long_mm IS NULL)`` of the passes over
    ``lv``'s stretch: the newest runs of each chunk."""
    c_lo = lv.i0 // CHUNK_POINTS
    t = TrackRunLevels.__table__
    keys = newest_runs(track_id, c_lo, c_lo + lv.level_mm.size // CHUNK_POINTS - 1)
    return list(
        session.execute(
            select(t.c.run_id, t.c.chunk, *columns, t.c.long_mm.is_(None)).join(
                keys, (keys.c.run_id == t.c.run_id) & (keys.c.chunk == t.c.chunk)
            )
        )
    )


def _spread(rows: Iterator[Any], lv: _Levels, unpack: Any) -> dict[int, NDArray[np.float32]]:
    """Each pass's chunks (``(run id, chunk, blob)`` rows) on ``lv``'s points, float32."""
    c_lo = lv.i0 // CHUNK_POINTS
    spread = unchunked_by_run(rows, c_lo, lv.level_mm.size, unpack, np.float32)
    return cast("dict[int, NDArray[np.float32]]", spread)


def _pending_long(session: Session, without_long: set[int]) -> frozenset[int]:
    """Those of ``without_long`` (run ids) whose long level is still being inverted."""
    if not without_long:
        return frozenset()
    return frozenset(
        session.scalars(select(Run.id).where(Run.id.in_(without_long), Run.long_level_pending))
    )


def with_passes(session: Session, track_id: int, lv: _Levels) -> _Levels:
    """``lv`` with the passes over its stretch: each chunk's newest aligned runs."""
    n = lv.level_mm.size
    t = TrackRunLevels.__table__
    rows = _pass_rows(session, track_id, lv, t.c.levels, t.c.long_mm)
    passes = _spread(((r, c, b) for r, c, b, _, _ in rows), lv, unpack_f4)
    longs = _spread(((r, c, b) for r, c, _, b, _ in rows), lv, unpack_long_level)
    recorded: dict[int, datetime | None] = {}
    speeds: dict[int, list[float]] = defaultdict(list)
    if passes:
        for rid, when, created, vid, v_lo, v_hi in session.execute(
            select(
                Run.id, Run.recorded_at, Run.created_at, Run.vehicle_id, Run.speed_min_mps,
                Run.speed_max_mps,
            ).where(Run.id.in_(list(passes)))
        ):  # fmt: skip
            recorded[int(rid)] = when or created
            speeds[int(vid)].append(0.5 * (float(v_lo) + float(v_hi)))
    return dataclasses.replace(
        lv, passes=passes, recorded=recorded, vehicle_speeds=dict(speeds),
        long_mm=_median(list(longs.values()), n), long_passes=longs,
        long_pending=_pending_long(session, {int(r[0]) for r in rows if r[4]}),
    )  # fmt: skip


def _median(arrays: list[NDArray[np.float32]], n: int) -> NDArray[np.float64]:
    """The median of the arrays' finite values point by point (NaN where none has one)."""
    if not arrays:
        return np.full(n, np.nan)
    stack = np.vstack(arrays)
    count = np.isfinite(stack).sum(axis=0)
    out = np.full(n, np.nan)
    has = count > 0
    out[has] = column_nanmedian(stack[:, has].astype(np.float64), count[has])
    return out


def _observability(
    session: Session, vehicle_speeds: dict[int, list[float]]
) -> list[dict[str, Any]]:
    out = []
    for vid, vs in sorted(vehicle_speeds.items()):
        veh = session.get(Vehicle, vid)
        speed = float(np.median(vs))
        if veh is None or not speed > 0:
            continue
        o = observability(vehicle_from_dict(veh.params_dict()), speed)
        out.append({"vehicle_id": vid, "vehicle": veh.name} | o.to_dict())
    return out


def _read_surveys(
    session: Session, track_id: int, i0: int, n: int
) -> list[tuple[Survey, NDArray[np.float64]]]:
    out: dict[int, NDArray[np.float64]] = {}
    s = SurveyLevels.__table__
    c_lo = i0 // CHUNK_POINTS
    for sid, chunk, blob in session.execute(
        select(s.c.survey_id, s.c.chunk, s.c.levels).where(
            s.c.track_id == track_id,
            s.c.chunk >= c_lo,
            s.c.chunk <= c_lo + n // CHUNK_POINTS,
        )
    ):
        at = (chunk - c_lo) * CHUNK_POINTS
        if at < 0 or at >= n:
            continue
        arr = out.setdefault(int(sid), np.full(n, np.nan))
        part = unpack_f4(blob)
        arr[at : at + part.size] = part[: n - at]
    surveys = {sv.id: sv for sv in session.scalars(select(Survey).where(Survey.id.in_(list(out))))}
    return [(surveys[k], v) for k, v in sorted(out.items()) if k in surveys]


# ------------------------------------------------------------------------------- analysis


def _f(v: float | None, nd: int = 3) -> float | None:
    return None if v is None or not math.isfinite(v) else round(float(v), nd)


def _iso(t: datetime | None) -> str | None:
    return None if t is None else t.isoformat().replace("+00:00", "Z")


def _crossing_dict(c: Any) -> dict[str, Any] | None:
    if c is None:
        return None
    return {
        "level": c[0],
        "limit_mm": c[1].limit,
        "reached": c[1].reached,
        "slope_mm_per_year": _f(c[1].slope_per_year),
        "date": _iso(c[1].date),
        "earliest": _iso(c[1].earliest),
        "latest": _iso(c[1].latest),
    }


def track_quality(
    session: Session,
    track: Track,
    section_m: float = 200.0,
    *,
    window: Window | None = None,
    traces: bool = False,
) -> dict[str, Any]:
    """The quality answer of ``track`` (see ``app.schemas.quality.QualityPublic``).

    ``section_m``: section length (m, from chainage 0); ``window``: the sections overlapping
    it and the defects peaking in it (filtered with a chunk of context either side, so a
    window's figures are the whole track's); ``traces``: add the D1/D2 levels (every 1 m).
    """
    window = window or Window()
    if not (10.0 <= section_m <= 10_000.0):
        raise Invalid(f"section_m {section_m:g} m not in 10..10000 m", field="section_m")
    limits, limits_set = load_quality_limits(session, track.id)
    speeds = load_line_speeds(session, track.id)
    lv = read_levels(session, track.id, window)
    answer = _answer_head(track, section_m, limits, limits_set)
    if lv is None:
        answer["notes"].append("no aligned run over this track yet")
        return answer
    q = Analysis(lv, limits, speeds, window)
    _say_d2_level(answer, q)
    answer["sections"] = _sections(q, section_m)
    answer["defects"] = _defects(q)
    answer["repeatability"] = _repeatability(lv)
    answer["observability"] = _observability(session, lv.vehicle_speeds)
    answer["survey_comparison"] = _survey_comparison(session, track.id, lv, section_m, q.bounds)
    if traces:
        answer["traces"] = _traces(q)
    return answer


def _answer_head(
    track: Track, section_m: float, limits: QualityLimits, limits_set: datetime | None
) -> dict[str, Any]:
    """The answer's fixed part: filters, limits' provenance; no results yet."""
    answer: dict[str, Any] = {
        "track_id": track.id,
        "track": track.name,
        "section_m": section_m,
        "filters": {
            name: {
                "lambda_min_m": b.lambda_min_m,
                "lambda_max_m": b.lambda_max_m,
                "order": b.order,
                "cutoff_db": b.cutoff_db,
                "zero_phase": True,
            }
            for name, b in BANDS.items()
        },  # fmt: skip
        "d2_band_m": [BANDS["D2"].lambda_min_m, BANDS["D2"].lambda_max_m],
        "d2_waiting_runs": [],
        "notes": [],
        "limits_default": limits_set is None,
        "unverified_limits": list(unverified_defaults(limits)),
        "limits_source": DEFAULTS_SOURCE if unverified_defaults(limits) else None,
        "sections": [],
        "defects": [],
        "repeatability": None,
        "observability": [],
        "survey_comparison": [],
        "traces": None,
    }
    # (unverified default limits are said by ``unverified_limits``, which the page and the
    # report each put in words once: a note as well said it twice)
    return answer


def _say_d2_level(answer: dict[str, Any], q: Analysis) -> None:
    """A note naming the passes D2 leaves out while their long level is being inverted, and
    ``d2_band_m`` and a note where D2 comes from the quality level: passes stored before
    their long level was kept (or too short for its band, or still waiting for it) hold only
    3-40 m."""
    if pending := sorted(q.lv.long_pending):
        answer["d2_waiting_runs"] = pending
        answer["notes"].append(
            f"D2 leaves out {len(pending)} pass(es) answered done moments ago whose "
            f"{LONG_LEVEL_LAMBDA_MAX_M:g} m level is still being inverted (run id "
            f"{', '.join(map(str, pending))}): ask again in a few seconds"
        )
    covered = np.isfinite(q.lv.level_mm)
    old = q.d2_from_quality[covered]
    if not old.any():
        return
    answer["d2_band_m"] = [BANDS["D2"].lambda_min_m, PRODUCT_BAND_MAX_M]
    answer["notes"].append(
        f"D2 over {100 * old.mean():.0f} % of the level comes from the stored "
        f"{PRODUCT_BAND_MAX_M:g} m level (its passes were stored before their "
        f"{LONG_LEVEL_LAMBDA_MAX_M:g} m level was kept, are too short for it, or wait for "
        "it): there it "
        f"covers {BANDS['D2'].lambda_min_m:g}-{PRODUCT_BAND_MAX_M:g} m of its 25-70 m and "
        "understates a recording car's D2 (sections' d2_level; processing the runs again "
        "keeps it)"
    )


class Analysis:
    """The track's level filtered to each band once, the passes' filtered levels on demand,
    and the window's bounds (m): what the sections, defects and traces share."""

    def __init__(
        self, lv: _Levels, limits: QualityLimits, speeds: tuple[LineSpeed, ...], window: Window
    ) -> None:
        self.lv, self.limits, self.speeds = lv, limits, speeds
        self.x = lv.chainage_m
        levels = {"quality": lv.level_mm}
        long = lv.long_mm if lv.long_mm is not None else np.full(lv.level_mm.size, np.nan)
        if np.isfinite(long).any():
            levels["long"] = long
        self.filt = band_levels(levels, GRID_STEP_M, trim_m=END_TRIM_M)[0]
        # where no pass kept its long level D2 falls back to the quality level, flagged
        self.d2_from_quality = np.isfinite(lv.level_mm) & ~np.isfinite(long)
        if "long" in levels and self.d2_from_quality.any():
            fallback = _band(BANDS["D2"], lv.level_mm)
            self.filt["D2"] = np.where(self.d2_from_quality, fallback, self.filt["D2"])
        self.lo = -math.inf if window.from_m is None else window.from_m
        self.hi = math.inf if window.to_m is None else window.to_m
        self._by_band: dict[str, dict[int, NDArray[np.float32]]] = {}

    @property
    def bounds(self) -> tuple[float, float]:
        return self.lo, self.hi

    def pass_levels(self, band: str) -> dict[int, NDArray[np.float32]]:
        """Each pass filtered to ``band`` (once), in recording order."""
        if band not in self._by_band:
            b = BANDS[band]
            lv = self.lv
            long = BAND_LEVEL.get(band) == "long"
            own = lv.long_passes if long else {}
            # a pass still waiting for its own level is left out, not filtered from another
            waiting = lv.long_pending if long else frozenset()
            self._by_band[band] = {
                r: _band(b, own.get(r, lv.passes[r])).astype(np.float32)
                for r in lv.ordered_runs
                if r not in waiting
            }
        return self._by_band[band]


def _sections(q: Analysis, section_m: float) -> list[dict[str, Any]]:
    """The sections overlapping the window that have a level, as answered."""
    stats = section_statistics(q.x, q.filt, section_m, min_coverage=MIN_SECTION_COVERAGE)
    now = utcnow()
    out = []
    for st in stats:
        if st.end_m <= q.lo or st.start_m > q.hi:
            continue
        m = (q.x >= st.start_m) & (q.x < st.end_m)
        covered = m & np.isfinite(q.lv.level_mm)
        if not covered.any():
            continue
        over = [
            rid for rid in q.lv.ordered_runs
            if np.isfinite(q.lv.passes[rid][m]).mean() >= MIN_SECTION_COVERAGE
        ]  # fmt: skip
        times = [t for r in over if (t := q.lv.recorded.get(r)) is not None]
        last = max(times) if times else None
        speed = speed_at(q.speeds, 0.5 * (st.start_m + st.end_m))
        d1 = st.sd_mm["D1"]
        pass_filt = q.pass_levels("D1")
        rep = (
            repeatability([pass_filt[r][m] for r in over], pairs="successive")
            if len(over) >= 2
            else None
        )
        cls = q.limits.quality_class(d1, speed)
        out.append({
            "start_m": st.start_m, "end_m": st.end_m,
            "d1_sd_mm": _f(d1), "d2_sd_mm": _f(st.sd_mm["D2"]),
            "coverage": _f(st.coverage, 2), "n_passes": len(over),
            "last_pass": _iso(last),
            "days_since_last_pass": None if last is None else _f(_days(now - last), 1),
            "repeatability_d1_mm": None if rep is None else _f(rep.r95_mm),
            "speed_kmh": speed, "quality_class": cls,
            "basis": _basis(float(q.lv.unloaded[covered].mean())),
            "d2_level": _d2_level(float(q.d2_from_quality[covered].mean())),
            "next_class": _next_class(q, m, over, cls, speed),
        })  # fmt: skip
    return out


def _d2_level(share_from_quality: float) -> str:
    if share_from_quality <= 0.05:
        return "long"
    return "quality" if share_from_quality >= 0.95 else "mixed"


def _basis(share_unloaded: float) -> str:
    if share_unloaded >= 0.95:
        return "unloaded"
    return "loaded" if share_unloaded <= 0.05 else "mixed"


def _next_class(
    q: Analysis, m: NDArray[np.bool_], over: list[int], cls: str | None, speed: float | None
) -> dict[str, Any] | None:
    """When the section's D1 SD, trended over its passes, reaches the next class's bound."""
    if cls is None or cls == "E" or len(over) < 3:
        return None
    pass_filt = q.pass_levels("D1")
    per_pass = [
        (t, float(np.nanstd(pass_filt[r][m])))
        for r in over
        if (t := q.lv.recorded.get(r)) is not None
    ]
    bounds = q.limits.class_sd_mm[speed_class(speed)]
    i = "ABCD".index(cls)
    crossing = predict_crossing([t for t, _ in per_pass], [v for _, v in per_pass], bounds[i])
    return _crossing_dict(("ABCDE"[i + 1], crossing))


def _defects(q: Analysis) -> list[dict[str, Any]]:
    """The isolated defects peaking in the window, most urgent then largest first."""
    out = []
    for name in BANDS:
        for d in isolated_defects(q.x, q.filt[name], name, q.limits, q.speeds):
            if not (q.lo <= d.peak_m <= q.hi):
                continue
            i = int(round(d.peak_m / GRID_STEP_M)) - q.lv.i0
            own_long = BAND_LEVEL.get(name) == "long" and not q.d2_from_quality[i]
            basis = "unloaded" if q.lv.unloaded[i] and not own_long else "loaded"
            out.append(_defect_dict(d, basis, q.limits, q.lv, q.pass_levels(name)))
    out.sort(key=lambda d: (LEVELS.index(d["level"]), -abs(d["value_mm"])))
    return out


def _repeatability(lv: _Levels) -> dict[str, Any]:
    rep_passes = [
        _band(REPEATABILITY_BAND, lv.passes[r]).astype(np.float32) for r in lv.ordered_runs
    ]
    rep = repeatability(rep_passes, pairs="successive")
    return {
        "band_m": [REPEATABILITY_BAND.lambda_min_m, REPEATABILITY_BAND.lambda_max_m],
        "r95_mm": _f(rep.r95_mm), "n_pairs": rep.n_pairs, "n_points": rep.n_points,
        "note": "loaded levels of successive passes (each run's own, before the separation)",
    }  # fmt: skip


def _traces(q: Analysis) -> dict[str, list[Any]]:
    """The D1/D2 levels every metre over the window."""
    step = int(round(1.0 / GRID_STEP_M))
    x = q.x
    keep = np.flatnonzero(np.isfinite(q.lv.level_mm) & (x >= q.lo) & (x <= q.hi))[::step]
    return {
        "chainage_m": [round(float(v), 2) for v in x[keep]],
        "d1_mm": [_f(float(v)) for v in q.filt["D1"][keep]],
        "d2_mm": [_f(float(v)) for v in q.filt["D2"][keep]],
    }


def _defect_dict(
    d: IsolatedDefect,
    basis: str,
    limits: QualityLimits,
    lv: _Levels,
    filtered: dict[int, NDArray[np.float32]],
) -> dict[str, Any]:
    band = d.band
    triple = limits.limits_at(band, d.speed_kmh)
    return {
        "peak_m": round(d.peak_m, 2), "start_m": round(d.start_m, 2), "end_m": round(d.end_m, 2),
        "band": band, "value_mm": _f(d.value_mm), "level": d.level, "speed_kmh": d.speed_kmh,
        "limits_mm": {"alert": triple[0], "intervention": triple[1], "immediate": triple[2]},
        "basis": basis, "next_limit": defect_next_limit(d, limits, lv, filtered),
    }  # fmt: skip


def pass_values(
    lv: _Levels, peak_m: float, filtered: dict[int, NDArray[np.float32]]
) -> list[tuple[int, datetime, float]]:
    """Each pass's value of a defect peaking at ``peak_m``: ``(run id, recorded, largest
    |level| within PEAK_MATCH_M of the peak, mm)``, passes in recording order."""
    i = int(round(peak_m / GRID_STEP_M)) - lv.i0
    k = int(round(PEAK_MATCH_M / GRID_STEP_M))
    near = slice(max(0, i - k), i + k + 1)
    out = []
    for rid, p in filtered.items():
        when = lv.recorded.get(rid)
        v = p[near]
        if when is not None and np.isfinite(v).any():
            out.append((rid, when, float(np.nanmax(np.abs(v)))))
    return out


def defect_next_limit(
    d: IsolatedDefect, limits: QualityLimits, lv: _Levels, filtered: dict[int, NDArray[np.float32]]
) -> dict[str, Any] | None:
    """When the defect's passes, trended, reach the next level it has not reached (3 passes)."""
    nxt = next_limit(d.value_mm, limits.limits_at(d.band, d.speed_kmh))
    if nxt is None:
        return None
    series = pass_values(lv, d.peak_m, filtered)
    if len(series) < 3:
        return None
    crossing = predict_crossing([t for _, t, _ in series], [v for _, _, v in series], nxt[1])
    return _crossing_dict((nxt[0], crossing))


def _survey_comparison(
    session: Session,
    track_id: int,
    lv: _Levels,
    section_m: float,
    bounds: tuple[float, float],
) -> list[dict[str, Any]]:
    out = []
    x = lv.chainage_m
    # each band from its own level where the passes kept it (as the sections)
    long = lv.long_mm if lv.long_mm is not None else lv.level_mm
    own = {
        n: np.where(np.isfinite(long), long, lv.level_mm)
        if BAND_LEVEL.get(n) == "long" else lv.level_mm
        for n in BANDS
    }  # fmt: skip
    for survey, level in _read_surveys(session, track_id, lv.i0, lv.level_mm.size):
        # both filtered over the same stretch: the filters' transients at the ends of a
        # coverage are then alike and cancel in the differences
        common = np.isfinite(level) & np.isfinite(lv.level_mm)
        both = {n: _band(b, np.where(common, level, np.nan)) for n, b in BANDS.items()}
        fleet = {n: _band(b, np.where(common, own[n], np.nan)) for n, b in BANDS.items()}
        s_stats = section_statistics(x, both, section_m, min_coverage=MIN_SECTION_COVERAGE)
        f_stats = section_statistics(x, fleet, section_m, min_coverage=MIN_SECTION_COVERAGE)
        rows = []
        for ss, fs in zip(s_stats, f_stats, strict=True):
            if not math.isfinite(ss.sd_mm["D1"]) or ss.end_m <= bounds[0] or ss.start_m > bounds[1]:
                continue
            m = (x >= ss.start_m) & (x < ss.end_m)
            err = np.abs(fleet["D1"][m] - both["D1"][m])
            rows.append({
                "start_m": ss.start_m, "end_m": ss.end_m,
                "survey_d1_sd_mm": _f(ss.sd_mm["D1"]), "fleet_d1_sd_mm": _f(fs.sd_mm["D1"]),
                "d1_sd_diff_mm": _f(fs.sd_mm["D1"] - ss.sd_mm["D1"]),
                "d2_sd_diff_mm": _f(fs.sd_mm["D2"] - ss.sd_mm["D2"]),
                "d1_peak_error_mm": _f(_nanmax(err)),
            })  # fmt: skip
        out.append({
            "survey_id": survey.id, "name": survey.name, "recorded_at": _iso(survey.recorded_at),
            "wheel_load_n": survey.wheel_load_n, "sections": rows,
        })  # fmt: skip
    return out


def _band(band: BandFilter, level: NDArray[np.floating[Any]]) -> NDArray[np.float64]:
    """A level filtered to ``band``, without the ringing stretches at its coverage's ends."""
    return trim_ends(band.apply(level, GRID_STEP_M), GRID_STEP_M)


def _days(span: Any) -> float:
    return float(span.total_seconds()) / 86400.0


def _nanmax(a: NDArray[np.float64]) -> float:
    return float(np.nanmax(a)) if np.isfinite(a).any() else math.nan
