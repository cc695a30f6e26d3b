"""EN 13848 limits by line speed: speed classes, isolated-defect limits (alert, intervention,
immediate action), quality-class bounds, and the isolated defects of a band-filtered level.

Units: chainage m, levels mm, line speeds km/h. Defaults and their sources: docs/method.md.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .errors import ParameterError
from .intervals import true_runs
from .track_quality import get_band

LEVELS = ("immediate", "intervention", "alert")
"""Limit levels of an isolated defect, most urgent first (EN 13848-5: IAL, IL, AL)."""

CLASSES = ("A", "B", "C", "D", "E")
"""Track geometry quality classes, best first (EN 13848-6 names them A to E)."""

SPEED_CLASSES_KMH = (80.0, 120.0, 160.0, 230.0, 300.0)
"""Upper bounds of EN 13848-5's speed classes, km/h (V <= 80, 80 < V <= 120, ...)."""


# --------------------------------------------------------------- line speeds and limit tables


@dataclass(frozen=True)
class LineSpeed:
    """Line speed ``speed_kmh`` (km/h) from ``from_m`` to ``to_m`` (m, aligned chainage)."""

    from_m: float
    to_m: float
    speed_kmh: float

    def __post_init__(self) -> None:
        if not (
            math.isfinite(self.from_m) and math.isfinite(self.to_m) and self.to_m > self.from_m
        ):
            raise ParameterError(
                f"line speed range {self.from_m}..{self.to_m} m: to_m must exceed from_m",
                field="to_m",
            )
        if not (0 < self.speed_kmh <= SPEED_CLASSES_KMH[-1]):
            raise ParameterError(
                f"line speed {self.speed_kmh} km/h not in (0, {SPEED_CLASSES_KMH[-1]:g}]",
                field="speed_kmh",
            )


def check_line_speeds(speeds: Sequence[LineSpeed]) -> tuple[LineSpeed, ...]:
    """The ranges sorted by chainage; ParameterError naming the first overlap."""
    ordered = tuple(sorted(speeds, key=lambda s: s.from_m))
    for p, q in zip(ordered, ordered[1:], strict=False):
        if q.from_m < p.to_m - 1e-9:
            raise ParameterError(
                f"line speed ranges overlap: {p.from_m:g}-{p.to_m:g} m and "
                f"{q.from_m:g}-{q.to_m:g} m",
                field="from_m",
            )
    return ordered


def speed_at(speeds: Sequence[LineSpeed], chainage_m: float) -> float | None:
    """Line speed at a chainage (km/h), None where no range holds it."""
    for s in speeds:
        if s.from_m <= chainage_m < s.to_m:
            return s.speed_kmh
    return None


def speed_class(speed_kmh: float | None) -> int:
    """Index into :data:`SPEED_CLASSES_KMH`; an unknown speed takes the fastest (strictest)."""
    if speed_kmh is None:
        return len(SPEED_CLASSES_KMH) - 1
    for i, top in enumerate(SPEED_CLASSES_KMH):
        if speed_kmh <= top:
            return i
    return len(SPEED_CLASSES_KMH) - 1


Triple = tuple[float | None, float | None, float | None]


def _check_triple(name: str, t: Sequence[float | None]) -> Triple:
    if len(t) != 3:
        raise ParameterError(f"{name}: expected [alert, intervention, immediate] mm", field=name)
    prev = None
    for lv, v in zip(("alert", "intervention", "immediate"), t, strict=True):
        if v is None:
            continue
        if not (math.isfinite(v) and v > 0):
            raise ParameterError(f"{name} {lv} limit must be > 0 mm or null, got {v}", field=name)
        if prev is not None and v < prev:
            raise ParameterError(
                f"{name}: {lv} limit {v:g} mm is below the less urgent one ({prev:g} mm)",
                field=name,
            )
        prev = v
    return (t[0], t[1], t[2])


DEFAULT_ISOLATED_MM: dict[str, tuple[Triple, ...]] = {
    "D1": ((12.0, 17.0, 28.0), (8.0, 12.0, 26.0), (6.0, 10.0, 23.0), (5.0, 9.0, 20.0),
           (4.0, 8.0, 16.0)),
    "D2": ((None, None, None), (None, None, None), (None, None, None), (8.0, 12.0, None),
           (6.0, 10.0, None)),
}  # fmt: skip
"""Isolated-defect limits, mean to peak (mm), per band and speed class: (alert, intervention,
immediate action). **Unverified**: EN 13848-5:2017 gives the immediate-action limits and
ranges for the alert and intervention limits by speed, but its tables could not be found in
any source open to the product (docs/method.md lists what was searched); these figures were
written from memory and are flagged as such in every answer that uses them
(:func:`unverified_defaults`). An infrastructure manager sets its own per track. D2 limits
apply above 160 km/h only."""

DEFAULT_CLASS_SD_MM: tuple[tuple[float, float, float, float], ...] = (
    (1.2, 1.8, 2.5, 3.2),
    (1.0, 1.5, 2.1, 2.8),
    (0.8, 1.2, 1.7, 2.3),
    (0.6, 0.9, 1.3, 1.8),
    (0.5, 0.8, 1.1, 1.5),
)
"""Upper SD of D1 per 200 m (mm) of classes A-D per speed class (E beyond D). **Unverified
placeholders**: EN 13848-6 names classes A-E, but its class bounds could not be found in any
source open to the product (docs/method.md); these are ordered with speed like its classes and
are flagged in every answer that uses them (:func:`unverified_defaults`)."""

DEFAULTS_SOURCE = (
    "product defaults written from memory, not checked against EN 13848-5:2017 (isolated "
    "defects) or EN 13848-6 (classes): their tables were not found in any source open to the "
    "product; set the track's own limits (PUT /tracks/{t}/quality-limits)"
)
"""What the defaults rest on, as answered next to :func:`unverified_defaults`."""


@dataclass(frozen=True)
class QualityLimits:
    """Isolated-defect limits and quality-class bounds by speed class.

    Parameters
    ----------
    isolated_mm : dict
        Band name -> per speed class ``(alert, intervention, immediate)`` mean-to-peak limits,
        mm (None switches one off); one entry per :data:`SPEED_CLASSES_KMH`.
    class_sd_mm : tuple
        Per speed class, the upper D1 SD (mm) of classes A, B, C, D (ascending).
    """

    isolated_mm: dict[str, tuple[Triple, ...]] = field(
        default_factory=lambda: dict(DEFAULT_ISOLATED_MM)
    )
    class_sd_mm: tuple[tuple[float, float, float, float], ...] = DEFAULT_CLASS_SD_MM

    def __post_init__(self) -> None:
        nc = len(SPEED_CLASSES_KMH)
        for band, rows in self.isolated_mm.items():
            get_band(band)
            if len(rows) != nc:
                raise ParameterError(
                    f"isolated_mm.{band}: need {nc} speed classes, got {len(rows)}",
                    field="isolated_mm",
                )
            for i, t in enumerate(rows):
                _check_triple(f"isolated_mm.{band}[{i}]", t)
        if len(self.class_sd_mm) != nc:
            raise ParameterError(f"class_sd_mm: need {nc} speed classes", field="class_sd_mm")
        for i, bounds in enumerate(self.class_sd_mm):
            if (
                len(bounds) != 4
                or any(not (b > 0) for b in bounds)
                or list(bounds) != sorted(bounds)
            ):
                raise ParameterError(
                    f"class_sd_mm[{i}]: need four ascending SDs > 0 (A, B, C, D upper bounds)",
                    field="class_sd_mm",
                )

    def level(self, band: str, speed_kmh: float | None, value_mm: float) -> str | None:
        """Most urgent level ``|value_mm|`` reaches in ``band`` at that line speed, or None."""
        rows = self.isolated_mm.get(band)
        if rows is None:
            return None
        alert, interv, immediate = rows[speed_class(speed_kmh)]
        v = abs(value_mm)
        for lv, lim in zip(LEVELS, (immediate, interv, alert), strict=True):
            if lim is not None and v >= lim:
                return lv
        return None

    def limits_at(self, band: str, speed_kmh: float | None) -> Triple:
        """``(alert, intervention, immediate)`` of ``band`` at that line speed, mm."""
        rows = self.isolated_mm.get(band)
        return rows[speed_class(speed_kmh)] if rows else (None, None, None)

    def quality_class(self, d1_sd_mm: float, speed_kmh: float | None) -> str | None:
        """Class A-E of a section's D1 SD at that line speed (None when the SD is NaN)."""
        if not math.isfinite(d1_sd_mm):
            return None
        for name, top in zip(CLASSES, self.class_sd_mm[speed_class(speed_kmh)], strict=False):
            if d1_sd_mm <= top:
                return name
        return CLASSES[-1]

    def to_dict(self) -> dict[str, object]:
        """Plain dict (lists), as stored and answered."""
        d = asdict(self)
        return {
            "isolated_mm": {k: [list(t) for t in v] for k, v in d["isolated_mm"].items()},
            "class_sd_mm": [list(t) for t in d["class_sd_mm"]],
        }

    @classmethod
    def from_dict(cls, d: dict[str, object]) -> QualityLimits:
        """Inverse of :meth:`to_dict`; keys left out take their defaults."""
        kw: dict[str, object] = {}
        iso = d.get("isolated_mm")
        if iso is not None:
            if not isinstance(iso, dict):
                raise ParameterError("isolated_mm must map band -> rows", field="isolated_mm")
            kw["isolated_mm"] = dict(DEFAULT_ISOLATED_MM) | {
                str(k): tuple(tuple(t) for t in v) for k, v in iso.items()
            }
        cls_sd = d.get("class_sd_mm")
        if cls_sd is not None:
            if not isinstance(cls_sd, list):
                raise ParameterError("class_sd_mm must be a list of rows", field="class_sd_mm")
            kw["class_sd_mm"] = tuple(tuple(t) for t in cls_sd)
        return cls(**kw)  # type: ignore[arg-type]


def unverified_defaults(limits: QualityLimits) -> tuple[str, ...]:
    """The parts of ``limits`` that are the product's unverified defaults
    (``isolated_mm.D1``, ``isolated_mm.D2``, ``class_sd_mm``): a table equal to its default is
    one, whether it was left out or restated."""
    out = [
        f"isolated_mm.{band}"
        for band, rows in limits.isolated_mm.items()
        if DEFAULT_ISOLATED_MM.get(band) == tuple(tuple(t) for t in rows)
    ]
    if tuple(tuple(t) for t in limits.class_sd_mm) == DEFAULT_CLASS_SD_MM:
        out.append("class_sd_mm")
    return tuple(out)


# ------------------------------------------------------------------------- isolated defects


@dataclass(frozen=True)
class IsolatedDefect:
    """One exceedance of a band's lowest limit: its peak (mean to peak, signed, mm)."""

    band: str
    peak_m: float
    start_m: float
    end_m: float
    value_mm: float
    level: str
    speed_kmh: float | None


def isolated_defects(
    chainage_m: ArrayLike,
    filtered_mm: NDArray[np.float64],
    band: str,
    limits: QualityLimits,
    speeds: Sequence[LineSpeed] = (),
) -> list[IsolatedDefect]:
    """Stretches where ``|filtered|`` reaches a limit of its line speed, one defect each at the
    largest ``|value|`` (mean-to-peak: the filtered level is zero-mean), ordered by chainage."""
    x = np.asarray(chainage_m, dtype=np.float64)
    v = np.asarray(filtered_mm, dtype=np.float64)
    rows = limits.isolated_mm.get(band)
    if rows is None or x.size == 0:
        return []
    speed = speeds_along(speeds, x)
    cls = np.array([speed_class(None)] * x.size) if not speeds else _classes(speed)
    # per point, the limits of its speed class (inf where a level is switched off)
    table = np.array([[np.inf if lim is None else lim for lim in t] for t in rows])
    lim = table[cls]
    mag = np.where(np.isfinite(v), np.abs(v), -np.inf)
    reached = (mag[:, None] >= lim).sum(axis=1)  # 0 none, 1 alert, 2 intervention, 3 immediate
    names = ("alert", "intervention", "immediate")
    hit = reached > 0
    out = []
    for a, b in true_runs(hit):
        i = a + int(np.argmax(mag[a:b]))
        sp = None if np.isnan(speed[i]) else float(speed[i])
        out.append(IsolatedDefect(band, float(x[i]), float(x[a]), float(x[b - 1]), float(v[i]),
                                  names[int(reached[i]) - 1], sp))  # fmt: skip
    return out


def speeds_along(speeds: Sequence[LineSpeed], chainage_m: ArrayLike) -> NDArray[np.float64]:
    """Line speed at each chainage (km/h, NaN where no range holds it); ``speeds`` ordered and
    not overlapping (:func:`check_line_speeds`)."""
    x = np.asarray(chainage_m, dtype=np.float64)
    out = np.full(x.shape, np.nan)
    if not speeds:
        return out
    starts = np.array([s.from_m for s in speeds])
    ends = np.array([s.to_m for s in speeds])
    vals = np.array([s.speed_kmh for s in speeds])
    k = np.searchsorted(starts, x, side="right") - 1
    ok = (k >= 0) & (x < ends[np.clip(k, 0, None)])
    out[ok] = vals[k[ok]]
    return out


def _classes(speed_kmh: NDArray[np.float64]) -> NDArray[np.int64]:
    top = np.array(SPEED_CLASSES_KMH)
    idx = np.searchsorted(top, speed_kmh, side="left")
    idx = np.clip(idx, 0, top.size - 1)
    return np.where(np.isnan(speed_kmh), top.size - 1, idx).astype(np.int64)


def next_limit(value_mm: float, triple: Triple) -> tuple[str, float] | None:
    """The next level ``|value_mm|`` has not reached yet and its limit (mm), or None."""
    v = abs(value_mm)
    for lv, lim in zip(("alert", "intervention", "immediate"), triple, strict=True):
        if lim is not None and v < lim:
            return lv, lim
    return None
