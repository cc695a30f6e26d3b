"""Soft-spot register: zones from many runs merged into tracked defects, trended and ranked.

Input is what each processed run found (in aligned chainage) and when the run was recorded;
output is one defect per place that keeps showing up, with its history, its trend over time
and a priority from limits in the style of EN 13848 (alert, intervention, immediate action).
"""

from __future__ import annotations

import math
import statistics
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field, fields
from datetime import datetime

import numpy as np

from .errors import ParameterError
from .intervals import merge_intervals

DAYS_PER_MONTH = 30.4375
LEVELS = ("immediate", "intervention", "alert")
"""Limit levels, most urgent first."""


@dataclass(frozen=True)
class Limits:
    """Limits on a defect's depth (mm) and stiffness loss (%), per level.

    A defect reaches a level when its depth *or* its stiffness loss reaches that level's
    value; ``None`` disables a criterion. Defaults are a starting point for loaded-profile
    dips measured on the 3-40 m band, to be set per track by the infrastructure manager.
    """

    alert_depth_mm: float | None = 0.15
    intervention_depth_mm: float | None = 0.25
    immediate_depth_mm: float | None = 0.40
    alert_loss_pct: float | None = 30.0
    intervention_loss_pct: float | None = 45.0
    immediate_loss_pct: float | None = 60.0

    def __post_init__(self) -> None:
        for kind, unit in (("depth_mm", "mm"), ("loss_pct", "%")):
            prev: tuple[str, float] | None = None
            for lv in ("alert", "intervention", "immediate"):
                name = f"{lv}_{kind}"
                v = getattr(self, name)
                if v is None:
                    continue
                if not (math.isfinite(v) and v > 0):
                    raise ParameterError(f"limit {name} must be > 0 {unit} or null", field=name)
                if prev is not None and v < prev[1]:
                    raise ParameterError(
                        f"{name} ({v:g} {unit}) is below {prev[0]} ({prev[1]:g} {unit}): limits "
                        "must grow from alert to intervention to immediate",
                        field=name,
                    )
                prev = (name, v)

    def level(self, depth_mm: float, loss_pct: float | None) -> str | None:
        """The most urgent level reached, or None."""
        for lv in LEVELS:
            d = getattr(self, f"{lv}_depth_mm")
            p = getattr(self, f"{lv}_loss_pct")
            if (d is not None and depth_mm >= d) or (
                p is not None and loss_pct is not None and loss_pct >= p
            ):
                return lv
        return None

    def to_dict(self) -> dict[str, float | None]:
        """Plain dict of the limits."""
        return asdict(self)


@dataclass(frozen=True)
class Observation:
    """One run's soft spot, in aligned chainage.

    Attributes
    ----------
    run_id : int
        The run.
    recorded_at : datetime
        When the run was recorded.
    start_m, end_m, peak_m : float
        Extent and deepest point, m.
    depth_mm : float
        Depth, mm.
    stiffness_loss_pct : float or None
        Estimated stiffness loss, %.
    """

    run_id: int
    recorded_at: datetime
    start_m: float
    end_m: float
    peak_m: float
    depth_mm: float
    stiffness_loss_pct: float | None


@dataclass(frozen=True)
class RunCoverage:
    """Where a run had a profile (aligned chainage, m) and when it was recorded."""

    run_id: int
    recorded_at: datetime
    from_m: float
    to_m: float


@dataclass(frozen=True)
class Defect:
    """A tracked defect of the register (chainage in m, depth in mm, loss in %)."""

    id: str
    start_m: float
    end_m: float
    peak_m: float
    first_seen: datetime
    last_seen: datetime
    runs_seen: int
    runs_covering: int
    depth_mm: float
    stiffness_loss_pct: float | None
    trend_mm_per_month: float
    trend_loss_pct_per_month: float
    status: str
    level: str | None
    priority: int
    level_since: datetime | None
    history: list[Observation] = field(default_factory=list)

    def to_dict(self, with_history: bool = False) -> dict[str, object]:
        """JSON-ready dict (datetimes as ISO 8601 strings)."""
        # not asdict(self): that would deep-copy the whole history for nothing
        d = {f.name: getattr(self, f.name) for f in fields(self) if f.name != "history"}
        for k in ("first_seen", "last_seen", "level_since"):
            d[k] = d[k].isoformat() if d[k] is not None else None
        if with_history:
            d["history"] = [
                {**asdict(o), "recorded_at": o.recorded_at.isoformat()} for o in self.history
            ]
        return d


@dataclass(frozen=True)
class RegisterConfig:
    """How observations become defects.

    Parameters
    ----------
    join_gap_m : float
        Observations whose extents overlap or lie closer than this merge, m.
    min_runs_trend : int
        Observations needed before a trend decides between worsening and stable.
    worsening_rate_mm_per_month : float
        Smallest depth trend called worsening, mm/month.
    worsening_loss_pct_per_month : float
        Smallest stiffness-loss trend called worsening, percentage points/month.
    """

    join_gap_m: float = 1.0
    min_runs_trend: int = 3
    worsening_rate_mm_per_month: float = 0.01
    worsening_loss_pct_per_month: float = 1.0


def _slope_per_month(t: np.ndarray, y: np.ndarray) -> tuple[float, float]:
    """Least-squares slope of y against time in months and its standard error."""
    if t.size < 2 or np.ptp(t) <= 0:
        return 0.0, float("inf")
    tm = (t - t.mean()) / DAYS_PER_MONTH
    sxx = float(np.dot(tm, tm))
    slope = float(np.dot(tm, y - y.mean()) / sxx)
    if t.size < 3:
        return slope, float("inf")
    resid = y - y.mean() - slope * tm
    se = math.sqrt(float(np.dot(resid, resid)) / (t.size - 2) / sxx)
    return slope, se


def build_register(
    observations: Sequence[Observation],
    coverage: Sequence[RunCoverage] = (),
    *,
    limits: Limits | None = None,
    config: RegisterConfig | None = None,
) -> list[Defect]:
    """Merge observations into defects, trend them and rank them.

    Parameters
    ----------
    observations : sequence of Observation
        Every soft spot of every run on the track, aligned chainage.
    coverage : sequence of RunCoverage
        Where each run had a profile (to count the runs that *could* have seen a defect).
    limits : Limits, optional
        Per-track limits (default :class:`Limits`).
    config : RegisterConfig, optional
        Merging and trend settings.

    Returns
    -------
    list of Defect
        Sorted by priority (1 = most urgent), then by depth, deepest first.
    """
    lim = limits or Limits()
    cfg = config or RegisterConfig()
    cov_from = np.array([c.from_m for c in coverage], dtype=np.float64)
    cov_to = np.array([c.to_m for c in coverage], dtype=np.float64)
    obs = sorted(observations, key=lambda o: (o.start_m, o.end_m))
    clusters = [
        [obs[i] for i in g]
        for g in merge_intervals([o.start_m for o in obs], [o.end_m for o in obs], cfg.join_gap_m)
    ]
    defects = []
    for cl in clusters:
        # one observation per run: a run that split a zone in two keeps its deeper part
        per_run: dict[int, Observation] = {}
        for o in cl:
            if o.run_id not in per_run or o.depth_mm > per_run[o.run_id].depth_mm:
                per_run[o.run_id] = o
        hist = sorted(per_run.values(), key=lambda o: (o.recorded_at, o.run_id))
        t = np.array([o.recorded_at.timestamp() / 86400.0 for o in hist])
        depth = np.array([o.depth_mm for o in hist])
        loss_vals = [o.stiffness_loss_pct for o in hist]
        have_loss = [v is not None and math.isfinite(v) for v in loss_vals]
        loss = np.array([v if ok else np.nan for v, ok in zip(loss_vals, have_loss, strict=True)])
        slope, se = _slope_per_month(t, depth)
        lm = np.isfinite(loss)
        lslope, lse = _slope_per_month(t[lm], loss[lm]) if lm.sum() >= 2 else (0.0, math.inf)
        # statistics.median: a cluster holds a few dozen values at most, where numpy's
        # per-call overhead dominated the register of a long line (thousands of clusters)
        start = float(statistics.median([o.start_m for o in hist]))
        end = float(statistics.median([o.end_m for o in hist]))
        peak = float(statistics.median([o.peak_m for o in hist]))
        latest = hist[-1]
        latest_loss = latest.stiffness_loss_pct
        if latest_loss is not None and not math.isfinite(latest_loss):
            latest_loss = None
        if len(hist) == 1:
            status = "new"
        elif len(hist) < cfg.min_runs_trend:
            status = "confirmed"
        elif (slope >= cfg.worsening_rate_mm_per_month and slope > 2 * se) or (
            lslope >= cfg.worsening_loss_pct_per_month and lslope > 2 * lse
        ):
            status = "worsening"
        else:
            status = "stable"
        level = lim.level(latest.depth_mm, latest_loss)
        level_since = None
        if level is not None:
            rank = LEVELS.index(level)
            for o in hist:
                lv = lim.level(o.depth_mm, o.stiffness_loss_pct)
                if lv is not None and LEVELS.index(lv) <= rank:
                    level_since = o.recorded_at
                    break
        covering = int(np.count_nonzero((cov_from <= start) & (cov_to >= end)))
        priority = (LEVELS.index(level) + 1) if level is not None else len(LEVELS) + 1
        first = hist[0]
        defects.append(
            Defect(
                id=f"{first.run_id}-{first.peak_m:.1f}",
                start_m=start,
                end_m=end,
                peak_m=peak,
                first_seen=hist[0].recorded_at,
                last_seen=latest.recorded_at,
                runs_seen=len(hist),
                runs_covering=max(covering, len(hist)),
                depth_mm=float(latest.depth_mm),
                stiffness_loss_pct=latest_loss,
                trend_mm_per_month=slope,
                trend_loss_pct_per_month=lslope,
                status=status,
                level=level,
                priority=priority,
                level_since=level_since,
                history=hist,
            )  # fmt: skip
        )
    defects.sort(key=lambda d: (d.priority, -d.depth_mm, d.start_m))
    return defects
