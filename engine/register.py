"""Soft-spot register: sightings from many passes merged into tracked defects, trended and ranked.

Input is every sighting of a soft spot in aligned chainage: what one processed run found on
its own (``pass``), what the track's geometry/stiffness separation found across passes of
different wheel loads (``separated``), and any other source in :data:`SOURCES`; each sighting
names the passes that support it. Output is one defect per place, with its evidence (which
kinds of sighting, how many passes, how many distinct wheel loads), its history, its trend
over time and a priority from limits in the style of EN 13848 (alert, intervention,
immediate action).
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
class Source:
    """A kind of sighting: how it is named to a person and how much its figures are trusted.

    ``rank`` orders the kinds when one defect has several: the defect's depth, loss and
    trend come from the lowest rank present (the separation knows the support from the rail's
    own geometry; one pass over rough rail does not).
    """

    label: str
    rank: int
    own_level: bool = False
    """Its sightings carry the level they reached by limits of their own (``Observation
    .level``), not the register's depth and loss limits."""


SOURCES: dict[str, Source] = {
    "separated": Source("separated", 0),
    "aggregate": Source("aggregate", 1),
    "pass": Source("single pass", 2),
    "isolated": Source("isolated level defect", 3, own_level=True),
}
"""The kinds of sighting the register accepts (``Observation.source``)."""


@dataclass(frozen=True)
class Support:
    """A pass behind a sighting: a run (or a survey) and when it was recorded.

    ``wheel_load_n`` is the pass's mean wheel load, N (None when unknown): passes of different
    loads are what lets the separation tell stiffness from geometry.
    """

    id: int
    recorded_at: datetime
    wheel_load_n: float | None = None
    kind: str = "run"


@dataclass(frozen=True)
class Observation:
    """One sighting of a soft spot, in aligned chainage.

    Attributes
    ----------
    run_id : int
        The run that made it (for a sighting across passes: its earliest supporting run).
    recorded_at : datetime
        When the sighting could first be made: the run's recording time, or for a sighting
        across passes the time its evidence became complete (see :func:`complete_at`).
    start_m, end_m, peak_m : float
        Extent and deepest point, m.
    depth_mm : float
        Depth, mm (for a separated spot: the dip it causes under the reference wheel load).
    stiffness_loss_pct : float or None
        Estimated stiffness loss, %.
    source : str
        Kind of sighting, a key of :data:`SOURCES`.
    support : tuple of Support
        The passes behind it; empty for a single run's sighting (the run itself).
    loss_lo_pct, loss_hi_pct : float or None
        Band of the loss, % (None when the source gives none).
    level : str or None
        For a source judged by its own limits (``Source.own_level``): the level this sighting
        reached, one of :data:`LEVELS`, or None below them.
    """

    run_id: int
    recorded_at: datetime
    start_m: float
    end_m: float
    peak_m: float
    depth_mm: float
    stiffness_loss_pct: float | None
    source: str = "pass"
    support: tuple[Support, ...] = ()
    loss_lo_pct: float | None = None
    loss_hi_pct: float | None = None
    level: str | None = None

    def __post_init__(self) -> None:
        if self.source not in SOURCES:
            raise ParameterError(
                f"sighting source {self.source!r} is not one of {sorted(SOURCES)}", field="source"
            )

    @property
    def passes(self) -> tuple[Support, ...]:
        """The supporting passes (the run itself for a single run's sighting)."""
        return self.support or (Support(self.run_id, self.recorded_at),)

    def to_dict(self) -> dict[str, object]:
        """JSON-ready dict (datetimes as ISO 8601; supporting passes as ``kind id`` labels)."""
        d: dict[str, object] = {
            f.name: getattr(self, f.name) for f in fields(self) if f.name != "support"
        }
        d["recorded_at"] = self.recorded_at.isoformat()
        d["passes"] = [f"{p.kind} {p.id}" for p in self.passes]
        return d


def count_loads(loads: Sequence[float | None], ratio: float) -> int:
    """Distinct wheel loads among ``loads`` (N): sorted, a load starts a new group when it is at
    least ``ratio`` times the smallest of the current group. Unknown loads (None) count as one
    group together when there is no known load, else not at all."""
    known = sorted(v for v in loads if v is not None and math.isfinite(v) and v > 0)
    if not known:
        return 1 if loads else 0
    groups, base = 1, known[0]
    for v in known[1:]:
        if v >= ratio * base:
            groups, base = groups + 1, v
    return groups


def complete_at(support: Sequence[Support], ratio: float) -> datetime:
    """When a sighting across passes became possible: the recording time of the pass that
    brought its passes to two distinct wheel loads (the last pass when they never span two)."""
    ordered = sorted(support, key=lambda p: (p.recorded_at, p.id))
    for i in range(1, len(ordered)):
        if count_loads([p.wheel_load_n for p in ordered[: i + 1]], ratio) >= 2:
            return ordered[i].recorded_at
    return ordered[-1].recorded_at


@dataclass(frozen=True)
class Evidence:
    """What one kind of sighting says about a defect: how many passes, how many loads."""

    kind: str
    passes: int
    loads: int
    sightings: int
    first_seen: datetime
    last_seen: datetime

    @property
    def text(self) -> str:
        """``separated: 4 passes, 2 loads`` — how a person reads it."""
        p = f"{self.passes} pass" + ("es" if self.passes != 1 else "")
        lo = f"{self.loads} load" + ("s" if self.loads != 1 else "")
        return f"{SOURCES[self.kind].label}: {p}, {lo}"

    def to_dict(self) -> dict[str, object]:
        """JSON-ready dict."""
        return {
            "kind": self.kind, "passes": self.passes, "loads": self.loads,
            "sightings": self.sightings, "first_seen": self.first_seen.isoformat(),
            "last_seen": self.last_seen.isoformat(), "text": self.text,
        }  # fmt: skip


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
    source: str = "pass"
    stiffness_loss_lo_pct: float | None = None
    stiffness_loss_hi_pct: float | None = None
    evidence: tuple[Evidence, ...] = ()
    history: list[Observation] = field(default_factory=list)
    next_limit: dict[str, object] | None = None
    """When the defect is predicted to reach its next level, with an interval (JSON-ready;
    None where its source gives no prediction)."""

    @property
    def evidence_text(self) -> str:
        """Every kind of evidence, most trusted first: ``separated: 4 passes, 2 loads``."""
        return "; ".join(e.text for e in self.evidence)

    def to_dict(self, with_history: bool = False) -> dict[str, object]:
        """JSON-ready dict (datetimes as ISO 8601 strings)."""
        # not asdict(self): that would deep-copy the whole history for nothing
        d = {
            f.name: getattr(self, f.name)
            for f in fields(self)
            if f.name not in ("history", "evidence")
        }
        for k in ("first_seen", "last_seen", "level_since"):
            d[k] = d[k].isoformat() if d[k] is not None else None
        d["evidence"] = [e.to_dict() for e in self.evidence]
        d["evidence_text"] = self.evidence_text
        if with_history:
            d["history"] = [o.to_dict() for o in self.history]
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
    load_ratio : float
        Wheel loads at least this ratio apart count as distinct (the separation's own
        ``SeparationConfig.min_load_ratio``).
    """

    join_gap_m: float = 1.0
    min_runs_trend: int = 3
    worsening_rate_mm_per_month: float = 0.01
    worsening_loss_pct_per_month: float = 1.0
    load_ratio: float = 1.1


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
        Every sighting on the track (single runs, the separation, ...), aligned chainage.
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
        defects.append(_defect(cl, cov_from, cov_to, lim, cfg))
    defects.sort(key=lambda d: (d.priority, -d.depth_mm, d.start_m))
    return defects


def _evidence(kind: str, obs: Sequence[Observation], ratio: float) -> Evidence:
    passes = {(p.kind, p.id): p for o in obs for p in o.passes}
    times = [p.recorded_at for p in passes.values()]
    return Evidence(
        kind=kind,
        passes=len(passes),
        loads=count_loads([p.wheel_load_n for p in passes.values()], ratio),
        sightings=len(obs),
        first_seen=min(times),
        last_seen=max(times),
    )


def _defect(
    cl: Sequence[Observation],
    cov_from: np.ndarray,
    cov_to: np.ndarray,
    lim: Limits,
    cfg: RegisterConfig,
) -> Defect:
    """One defect from the sightings of one place."""
    by_kind: dict[str, list[Observation]] = {}
    for o in cl:
        by_kind.setdefault(o.source, []).append(o)
    # one single-run sighting per run: a run that split a zone in two keeps its deeper part
    if "pass" in by_kind:
        per_run: dict[int, Observation] = {}
        for o in by_kind["pass"]:
            if o.run_id not in per_run or o.depth_mm > per_run[o.run_id].depth_mm:
                per_run[o.run_id] = o
        by_kind["pass"] = list(per_run.values())
    kinds = sorted(by_kind, key=lambda k: SOURCES[k].rank)
    for k in kinds:
        by_kind[k].sort(key=lambda o: (o.recorded_at, o.run_id))
    evidence = tuple(_evidence(k, by_kind[k], cfg.load_ratio) for k in kinds)
    # the figures, extent and trend of the most trusted kind present
    main = kinds[0]
    hist = by_kind[main]
    t = np.array([o.recorded_at.timestamp() / 86400.0 for o in hist])
    depth = np.array([o.depth_mm for o in hist])
    loss_vals = [o.stiffness_loss_pct for o in hist]
    loss = np.array([v if v is not None and math.isfinite(v) else np.nan for v in loss_vals])
    slope, se = _slope_per_month(t, depth)
    lm = np.isfinite(loss)
    lslope, lse = _slope_per_month(t[lm], loss[lm]) if lm.sum() >= 2 else (0.0, math.inf)
    # statistics.median: a cluster holds a few dozen values at most, where numpy's per-call
    # overhead dominated the register of a long line (thousands of clusters)
    start = float(statistics.median([o.start_m for o in hist]))
    end = float(statistics.median([o.end_m for o in hist]))
    peak = float(statistics.median([o.peak_m for o in hist]))
    latest = hist[-1]
    latest_loss = latest.stiffness_loss_pct
    if latest_loss is not None and not math.isfinite(latest_loss):
        latest_loss = None
    supporters = {(p.kind, p.id): p for k in kinds for o in by_kind[k] for p in o.passes}
    n_passes = len(supporters)
    if n_passes == 1:
        status = "new"
    elif len(hist) < cfg.min_runs_trend:
        # independent passes support it, but too few successive sightings for a trend
        status = "confirmed"
    elif (slope >= cfg.worsening_rate_mm_per_month and slope > 2 * se) or (
        lslope >= cfg.worsening_loss_pct_per_month and lslope > 2 * lse
    ):
        status = "worsening"
    else:
        status = "stable"

    def judge(o: Observation) -> str | None:
        if SOURCES[main].own_level:
            return o.level
        return lim.level(o.depth_mm, o.stiffness_loss_pct)

    level = judge(latest)
    level_since = None
    if level is not None:
        rank = LEVELS.index(level)
        for o in hist:
            lv = judge(o)
            if lv is not None and LEVELS.index(lv) <= rank:
                level_since = o.recorded_at
                break
    covering = int(np.count_nonzero((cov_from <= start) & (cov_to >= end)))
    priority = (LEVELS.index(level) + 1) if level is not None else len(LEVELS) + 1
    times = [p.recorded_at for p in supporters.values()]
    history = sorted(
        (o for k in kinds for o in by_kind[k]), key=lambda o: (o.recorded_at, o.run_id)
    )
    first = history[0]
    return Defect(
        id=f"{first.run_id}-{first.peak_m:.1f}",
        start_m=start,
        end_m=end,
        peak_m=peak,
        first_seen=min(times),
        last_seen=max(times),
        runs_seen=n_passes,
        runs_covering=max(covering, n_passes),
        depth_mm=float(latest.depth_mm),
        stiffness_loss_pct=latest_loss,
        trend_mm_per_month=slope,
        trend_loss_pct_per_month=lslope,
        status=status,
        level=level,
        priority=priority,
        level_since=level_since,
        source=main,
        stiffness_loss_lo_pct=latest.loss_lo_pct if latest_loss is not None else None,
        stiffness_loss_hi_pct=latest.loss_hi_pct if latest_loss is not None else None,
        evidence=evidence,
        history=history,
    )
