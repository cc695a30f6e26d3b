"""The ring at a pass's ends: a few shapes per vehicle and speed, fitted across passes.

A pass's level rings over its first and last ~100 m: the log lacks the body's response to the
rail before its first sample and after its last, and the band-limited inverse spreads that
over about ``lambda_max`` (docs/method.md "Edges of a pass"). The error is linear in what is
missing and, for one vehicle at one speed, nearly the same few shapes from pass to pass: six
per end hold 99 % of its energy on held-out rail (docs/accuracy.md "The ends' ring as a few
shapes"). The shapes are made here with the engine's own model (a simulated pass cut and
inverted against the whole pass) and fitted, robustly, to the level differences of every pair
of passes, where the rail cancels; each pass's fitted ring is then taken off its level and the
separation weighs its ends by what is left (``SeparationConfig.end_ring_edge_factor``).
"""

from __future__ import annotations

import dataclasses
import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass, replace
from functools import lru_cache
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from .errors import InversionError, check_settings

if TYPE_CHECKING:
    from .passes import Pass
    from .results import ProcessResult
    from .runlog import RunLog
    from .vehicle_kinds import Vehicle


@dataclass(frozen=True)
class EndRingConfig:
    """How the shapes are made and fitted.

    Attributes
    ----------
    n_shapes : int
        Shapes per end of a pass (6: 99 % of the end error's energy, measured).
    span_m : float
        Length of each end's shapes from the pass's first / up to its last level sample, m.
    fade_m : float
        The shapes are tapered to zero over their far ``fade_m`` m (a shape cut off would leave
        a step in the level), m.
    rail_m, cut_m, cut_every_m : float
        The simulated pass that makes the shapes: its rail's length, the cuts' length and
        spacing (cuts start 150 m in), m.
    rail_seed, rails : int
        Seed of the first rail (German low-disturbance, 5 % support scatter; its sensor noise's
        is the next) and how many rails (seeds ``rail_seed``, ``rail_seed + 2``, ...).
    speed_bin_mps : float
        Shapes are made at the pass's mean speed rounded to this, m/s (1-2 m/s off changes
        them by under 1 % of the error's energy, measured).
    huber : float
        The robust fit's Huber threshold in robust standard deviations of the residual.
    iterations : int
        Reweighting rounds of the robust fit.
    prior_scale : float
        The fit's prior on a shape's weight is its RMS over the cuts times this (loose: the
        prior stops a shape the cuts hardly needed from being fitted to noise, no more).
    """

    n_shapes: int = 6
    span_m: float = 120.0
    fade_m: float = 30.0
    rail_m: float = 1100.0
    cut_m: float = 300.0
    cut_every_m: float = 45.0
    rail_seed: int = 9101
    rails: int = 1
    speed_bin_mps: float = 2.0
    huber: float = 1.5
    iterations: int = 8
    prior_scale: float = 3.0

    def __post_init__(self) -> None:
        check_settings(
            self,
            {
                "n_shapes": self.n_shapes >= 1,
                "rails": self.rails >= 1,
                "span_m": self.span_m > 0,
                "fade_m": 0 < self.fade_m <= self.span_m,
                "cut_m": self.cut_m > self.span_m,
                "rail_m": self.rail_m >= self.cut_m + 300.0,
                "cut_every_m": self.cut_every_m > 0,
                "speed_bin_mps": self.speed_bin_mps > 0,
                "huber": self.huber > 0,
                "iterations": self.iterations >= 1,
                "prior_scale": self.prior_scale > 0,
            },
            "end rings",
        )


@dataclass(frozen=True, eq=False)
class EndRingShapes:
    """A vehicle's ring shapes at one speed.

    Attributes
    ----------
    start, end : ndarray
        ``(n_shapes, n)`` shapes, mm per unit coefficient, on a grid of ``step_m``: ``start``
        from the pass's first level sample on, ``end`` up to its last (the last column is that
        sample). Orthonormal rows, already tapered at their far end.
    step_m : float
        Their grid step, m.
    start_rms, end_rms : ndarray
        ``(n_shapes,)`` RMS weight of each shape over the cuts that made it, mm: the fit's
        prior on a pass's weights (a shape the cuts hardly needed is not fitted to noise).
    """

    start: NDArray[np.float64]
    end: NDArray[np.float64]
    step_m: float
    start_rms: NDArray[np.float64]
    end_rms: NDArray[np.float64]


def _cut(log: RunLog, t0: float, t1: float) -> RunLog:
    """The samples of ``log`` in [t0, t1) s, its time from zero."""
    keep = (log.time_s >= t0) & (log.time_s < t1)
    fields: dict[str, Any] = {
        f.name: (getattr(log, f.name)[keep] if getattr(log, f.name) is not None else None)
        for f in dataclasses.fields(log)
    }
    fields["time_s"] = fields["time_s"] - fields["time_s"][0]
    return type(log)(**fields)


def _fade(n: int, step: float, cfg: EndRingConfig) -> NDArray[np.float64]:
    far = (n - 1 - np.arange(n)) * step  # distance to the shapes' far end
    return np.asarray(0.5 - 0.5 * np.cos(np.pi * np.clip(far / cfg.fade_m, 0.0, 1.0)))


@lru_cache(maxsize=64)
def _shapes(vehicle: Vehicle, speed_mps: float, cfg: EndRingConfig) -> EndRingShapes:
    from .pipeline import process_run
    from .setup import RunSetup, prepare_run
    from .synthetic import REALISTIC_SENSOR, make_run, make_track

    sensor = replace(REALISTIC_SENSOR, sample_rate_hz=500.0)
    starts, ends = [], []
    step = 0.0
    for seed in range(cfg.rail_seed, cfg.rail_seed + 2 * cfg.rails, 2):
        track = make_track(cfg.rail_m, jitter=0.05, irregularity="german-low", seed=seed)
        run = make_run(track=track, vehicle=vehicle, speed=speed_mps, sensor=sensor,
                       sim_rate_hz=500.0, seed=seed + 1, start_chainage_m=12.0)  # fmt: skip
        whole = process_run(prepare_run(run.log, RunSetup(run.start_chainage_m, vehicle=vehicle)))
        grid = whole.chainage_m
        step = float(grid[1] - grid[0])
        n = int(round(cfg.span_m / step))
        for c0 in np.arange(150.0, cfg.rail_m - cfg.cut_m - 150.0, cfg.cut_every_m):
            t0 = float(c0) / speed_mps
            part = process_run(
                prepare_run(
                    _cut(run.log, t0, t0 + cfg.cut_m / speed_mps),
                    RunSetup(run.start_chainage_m + speed_mps * t0, vehicle=vehicle),
                )
            )
            lvl = np.interp(grid, part.chainage_m, part.level_mm, left=np.nan, right=np.nan)
            idx = np.flatnonzero(np.isfinite(lvl))
            err = lvl - whole.level_mm
            if idx.size < 2 * n or not np.isfinite(err[idx[0] : idx[-1] + 1]).all():
                continue
            starts.append(err[idx[0] : idx[0] + n])
            ends.append(err[idx[-1] - n + 1 : idx[-1] + 1])
    if len(starts) < cfg.n_shapes:
        raise InversionError(
            f"no end ring shapes for this vehicle at {speed_mps:.1f} m/s: {len(starts)} of the "
            f"simulated pass's cuts inverted, {cfg.n_shapes} needed"
        )
    k = cfg.n_shapes
    fade = _fade(n, step, cfg)
    _, s_start, v_start = np.linalg.svd(np.array(starts), full_matrices=False)
    _, s_end, v_end = np.linalg.svd(np.array(ends), full_matrices=False)
    rows = math.sqrt(len(starts))
    return EndRingShapes(
        v_start[:k] * fade, v_end[:k] * fade[::-1], step, s_start[:k] / rows, s_end[:k] / rows
    )


def ring_speed_mps(speed_min_mps: float, speed_max_mps: float) -> float:
    """The speed a run's ring shapes are made at: the mean of its slowest and fastest, m/s."""
    return 0.5 * (float(speed_min_mps) + float(speed_max_mps))


def run_speed_mps(result: ProcessResult) -> float:
    """:func:`ring_speed_mps` of a processed run, m/s."""
    return ring_speed_mps(result.quality.speed_min_mps, result.quality.speed_max_mps)


def end_ring_shapes(
    vehicle: Vehicle, speed_mps: float, config: EndRingConfig | None = None
) -> EndRingShapes:
    """The ring shapes of ``vehicle`` at ``speed_mps`` (m/s, rounded to the config's bin).

    Made once per vehicle, speed bin and configuration in a process (about 2.5 s of CPU: one
    1100 m pass simulated and 12 cuts of it inverted, with the product's processing defaults)
    and kept. Raises :class:`~engine.errors.InversionError` when the simulated pass cannot be
    inverted often enough to make them.

    Parameters
    ----------
    vehicle : Vehicle
        The vehicle the passes are processed with (any kind).
    speed_mps : float
        The pass's mean speed, m/s (> 0).
    config : EndRingConfig, optional

    Returns
    -------
    EndRingShapes
    """
    cfg = config or EndRingConfig()
    if not (math.isfinite(speed_mps) and speed_mps > 0):
        raise ValueError(f"speed_mps must be a positive speed in m/s, got {speed_mps}")
    binned = max(1.0, math.floor(speed_mps / cfg.speed_bin_mps + 0.5)) * cfg.speed_bin_mps
    return _shapes(vehicle, float(binned), cfg)


def _columns(
    shapes: EndRingShapes, n: int, step: float, first: int, last: int
) -> NDArray[np.float64]:
    """A pass's start and end shapes on a grid of ``n`` points of ``step`` m, anchored at its
    first and last level sample: ``(n, 2 * n_shapes)``, zero outside the spans."""
    k, m = shapes.start.shape
    span = (m - 1) * shapes.step_m
    x = np.arange(n) * step
    cols = np.zeros((n, 2 * k))
    for rows, origin, at in ((shapes.start, first, 0), (shapes.end, last, k)):
        # start: 0 at the first sample; end: ``span`` at the last
        xs = x - x[origin] + (span if at else 0.0)
        inside = (xs >= 0) & (xs <= span)
        xb = np.arange(m) * shapes.step_m
        for i in range(k):
            cols[inside, at + i] = np.interp(xs[inside], xb, rows[i])
    return cols


def _pair_rows(
    j: int, k: int, idx: NDArray[np.intp], cols: dict[int, NDArray[np.float64]],
    at: dict[int, slice],
) -> tuple[NDArray[np.float64], NDArray[np.intp]]:  # fmt: skip
    """The design rows of the difference ``level_j - level_k`` at ``idx``, on the two passes'
    own unknowns only, and where those sit among all the unknowns."""
    parts, where = [], []
    for p, sign in ((j, 1.0), (k, -1.0)):
        if p in cols:
            parts.append(sign * cols[p][idx])
            where.append(np.arange(at[p].start, at[p].stop))
    return np.hstack(parts), np.concatenate(where)


def _robust_pairs(
    pairs: list[tuple[int, int, NDArray[np.intp]]],
    levels: list[NDArray[np.float64]],
    cols: dict[int, NDArray[np.float64]],
    at: dict[int, slice],
    prior_rms: NDArray[np.float64],
    cfg: EndRingConfig,
) -> NDArray[np.float64]:
    """Huber-weighted least squares of every pair's level difference on the passes' shapes (a
    zone's dip is an outlier to shapes tens of metres long), each weight with its prior
    (``prior_rms``, mm: zero mean, the cuts' RMS) against the residual's spread; minimum
    norm where the passes share a shape (what all share cancels in the differences)."""
    offset = prior_rms.size
    blocks = [(*_pair_rows(j, k, idx, cols, at), (levels[j] - levels[k])[idx])
              for j, k, idx in pairs]  # fmt: skip
    weights = [np.ones(y.size) for *_, y in blocks]
    coef: NDArray[np.float64] = np.zeros(offset)
    noise = 0.0  # the residual's robust spread, mm: none before the first fit
    for _ in range(cfg.iterations):
        ata = np.diag((noise / prior_rms) ** 2)
        aty = np.zeros(offset)
        for (a, where, y), w in zip(blocks, weights, strict=True):
            aw = a * w[:, None]
            ata[np.ix_(where, where)] += aw.T @ a
            aty[where] += aw.T @ y
        coef = np.asarray(np.linalg.lstsq(ata, aty, rcond=1e-10)[0], dtype=np.float64)
        resid = [y - a @ coef[where] for a, where, y in blocks]
        r = np.concatenate(resid)
        s = 1.4826 * float(np.median(np.abs(r - np.median(r))))
        if not s > 0:
            break
        noise = s
        weights = [np.minimum(1.0, cfg.huber * s / np.maximum(np.abs(e), 1e-12)) for e in resid]
    return coef


def fit_end_rings(passes: Sequence[Pass], config: EndRingConfig | None = None) -> list[Pass]:
    """The passes with their fitted end rings taken off their levels.

    Every pass carrying :attr:`Pass.end_rings` gets its start and end shapes, anchored at its
    first and last level sample; all are fitted at once to the level differences of every
    pair of passes overlapping by at least one point, robustly. What every pass shares (the
    rail, a ring common to all) cancels in the differences and is left. Passes without shapes
    (surveys) take part as they are. With fewer than two passes, or none with shapes, the
    passes come back unchanged.

    Parameters
    ----------
    passes : sequence of Pass
        Aligned passes on grids of one step (m), levels in mm.
    config : EndRingConfig, optional

    Returns
    -------
    list of Pass
        Levels corrected (mm); everything else as given.
    """
    cfg = config or EndRingConfig()
    fitted = [j for j, p in enumerate(passes) if p.end_rings is not None]
    if len(passes) < 2 or not fitted:
        return list(passes)
    step = float(passes[0].chainage_m[1] - passes[0].chainage_m[0])
    x0 = min(float(p.chainage_m[0]) for p in passes)
    x1 = max(float(p.chainage_m[-1]) for p in passes)
    grid = x0 + step * np.arange(int(round((x1 - x0) / step)) + 1)
    levels = [np.interp(grid, p.chainage_m, p.level_mm, left=np.nan, right=np.nan) for p in passes]
    cols: dict[int, NDArray[np.float64]] = {}
    for j in fitted:
        idx = np.flatnonzero(np.isfinite(levels[j]))
        if idx.size:
            cols[j] = _columns(passes[j].end_rings, grid.size, step, int(idx[0]), int(idx[-1]))  # type: ignore[arg-type]
    at, offset = {}, 0
    for j, c in cols.items():
        at[j] = slice(offset, offset + c.shape[1])
        offset += c.shape[1]
    # where each pass's shapes reach (none without shapes), once per pass
    none = np.zeros(grid.size, dtype=bool)
    span = {j: np.any(c != 0.0, axis=1) for j, c in cols.items()}
    # one block of rows per pair of overlapping passes, where either has a shape: the normal
    # equations are summed pair by pair (many passes stay small: 12 unknowns per pass)
    pairs = []
    for j, k in itertools.combinations(range(len(passes)), 2):
        if j not in cols and k not in cols:
            continue
        ok = np.isfinite(levels[j]) & np.isfinite(levels[k])
        ok &= span.get(j, none) | span.get(k, none)
        if ok.any():
            pairs.append((j, k, np.flatnonzero(ok)))
    if not pairs:
        return list(passes)
    prior = np.concatenate(
        [np.concatenate([passes[j].end_rings.start_rms, passes[j].end_rings.end_rms])  # type: ignore[union-attr]
         for j in cols]
    )  # fmt: skip
    coef = _robust_pairs(pairs, levels, cols, at, cfg.prior_scale * prior, cfg)
    out = list(passes)
    for j, c in cols.items():
        ring = c @ coef[at[j]]
        out[j] = replace(
            passes[j], level_mm=passes[j].level_mm - np.interp(passes[j].chainage_m, grid, ring)
        )
    return out
