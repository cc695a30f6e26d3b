"""Passes over a track for the separation: from processed runs, on one grid, aligned."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from .align import END_RING_M, align_profiles
from .end_rings import EndRingShapes
from .errors import ParameterError
from .pipeline import fuse_axles
from .results import ProcessResult


@dataclass(frozen=True)
class Pass:
    """One aligned pass over the track (a run or a survey).

    Attributes
    ----------
    chainage_m : ndarray
        Regular grid on the track's chainage, m, increasing (already aligned).
    level_mm : ndarray
        Loaded level in the product's band (3-40 m), mm, positive up; NaN = not covered.
    force_n : ndarray or float
        Wheel force along the grid (static + dynamic), N, compression positive; or a constant.
    kind : str
        ``"run"`` or ``"survey"``.
    label : str
        E.g. the run id, for "which runs contributed".
    wheel_offsets_m : tuple of float
        The wheels of the measured point relative to it, m, sharing ``force_n`` equally:
        ``(0,)`` for a half car's axle or a survey's point load, ``(+a/2, -a/2)`` for a bogie
        of wheelbase ``a`` (the vehicle's ``axle_wheel_offsets_m``).
    end_rings : EndRingShapes, optional
        The ring shapes of the pass's vehicle at its speed
        (:func:`engine.end_rings.end_ring_shapes`): the separation fits them across the passes
        and takes them off this pass's level (:func:`engine.end_rings.fit_end_rings`). None:
        the level is taken as it is (a survey).
    """

    chainage_m: NDArray[np.float64]
    level_mm: NDArray[np.float64]
    force_n: NDArray[np.float64] | float
    kind: str = "run"
    label: str = ""
    wheel_offsets_m: tuple[float, ...] = (0.0,)
    end_rings: EndRingShapes | None = None


def pass_from_result(
    result: ProcessResult,
    *,
    offset_m: float = 0.0,
    kind: str = "run",
    label: str = "",
    wheel_offsets_m: tuple[float, ...] = (0.0,),
    end_rings: EndRingShapes | None = None,
) -> Pass:
    """A pass from one processed run: fused level and the mean of both axles' wheel forces.

    ``offset_m`` (m) is added to the run's chainage (its alignment to the track);
    ``wheel_offsets_m`` are the vehicle's wheels about a measured point
    (``vehicle.axle_wheel_offsets_m[0]``; a half car's axle by default); ``end_rings`` the
    vehicle's ring shapes at the run's speed (:func:`engine.end_rings.end_ring_shapes`).
    """
    if result.front_force_n is None or result.rear_force_n is None:
        raise ParameterError("the processed run has no wheel force (front_force_n) to separate")
    force = fuse_axles(result.front_force_n, result.rear_force_n)
    return Pass(
        result.chainage_m + offset_m, result.level_mm, force, kind, label, tuple(wheel_offsets_m),
        end_rings,
    )  # fmt: skip


def align_passes(
    passes: Sequence[Pass],
    *,
    max_shift_m: float = 10.0,
    recentre: bool = True,
    stretch_m: float = 2000.0,
    edge_m: float = END_RING_M,
) -> tuple[list[Pass], list[float]]:
    """Align passes to one another by cross-correlating their levels.

    Each pass is aligned to the mean of the passes already aligned (the aggregate), on at
    most ``stretch_m`` metres of their common stretch (cost independent of the run length).
    With ``recentre`` the common frame is then shifted so that the offsets average zero: each
    logged start chainage is an independent estimate of the true one, so their mean is the
    best estimate of the track's frame. A pass whose alignment is not trusted keeps its
    logged chainage. Each pass's first and last ``edge_m`` metres (its level's ring) are left
    out of its comparison. Returns the shifted passes and the offsets, m.
    """
    if not passes:
        return [], []
    step = float(passes[0].chainage_m[1] - passes[0].chainage_m[0])
    grid, levels, _ = on_grid(passes, step)
    total = np.where(np.isfinite(levels[0]), levels[0], 0.0)
    count = np.isfinite(levels[0]).astype(float)
    offsets = [0.0]
    for j, p in enumerate(passes[1:], start=1):
        with np.errstate(invalid="ignore", divide="ignore"):
            ref = np.where(count > 0, total / count, np.nan)
        both = np.flatnonzero(np.isfinite(ref) & np.isfinite(levels[j]))
        off = 0.0
        if both.size:
            mid = 0.5 * (grid[both[0]] + grid[both[-1]])
            lo, hi = np.searchsorted(grid, [mid - 0.5 * stretch_m, mid + 0.5 * stretch_m])
            lo, hi = max(lo, both[0]), min(hi, both[-1] + 1)
            if hi - lo >= 8:
                sel = slice(int(lo), int(hi))
                pl = np.asarray(p.level_mm, dtype=float)
                k0, k1 = np.searchsorted(
                    p.chainage_m, [grid[lo] - max_shift_m, grid[hi - 1] + max_shift_m]
                )
                a = align_profiles(grid[sel], ref[sel], p.chainage_m[k0:k1], pl[k0:k1],
                                   max_shift_m=max_shift_m, edge_m=edge_m)  # fmt: skip
                off = a.offset_m if a.ok else 0.0
        offsets.append(off)
        shifted = np.interp(grid, p.chainage_m + off, np.asarray(p.level_mm, dtype=float),
                            left=np.nan, right=np.nan)  # fmt: skip
        ok = np.isfinite(shifted)
        total[ok] += shifted[ok]
        count[ok] += 1.0
    shift = -float(np.mean(offsets)) if recentre else 0.0
    out = [
        replace(p, chainage_m=p.chainage_m + o + shift)
        for p, o in zip(passes, offsets, strict=True)
    ]
    return out, [o + shift for o in offsets]


def column_mean_sd(x: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Mean and standard deviation of each column over its finite values (NaN if none)."""
    ok = np.isfinite(x)
    n = ok.sum(axis=0)
    xs = np.where(ok, x, 0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.where(n > 0, xs.sum(axis=0) / n, np.nan)
        var = np.where(n > 0, (np.where(ok, x - mean, 0.0) ** 2).sum(axis=0) / n, np.nan)
    return mean, np.sqrt(var)


def _name(j: int, p: Pass) -> str:
    """How a message names a pass: its label (what the caller knows it by), else its place."""
    return p.label or f"pass {j} ({p.kind})"


def on_grid(
    passes: Sequence[Pass], step: float
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Common grid and every pass's level (mm) and force (N) on it (NaN where not covered)."""
    lo = min(float(np.nanmin(p.chainage_m)) for p in passes)
    hi = max(float(np.nanmax(p.chainage_m)) for p in passes)
    grid = np.arange(math.floor(lo / step) * step, hi + 1e-9, step)
    levels = np.full((len(passes), grid.size), np.nan)
    forces = np.full((len(passes), grid.size), np.nan)
    for j, p in enumerate(passes):
        x = np.asarray(p.chainage_m, dtype=float)
        y = np.asarray(p.level_mm, dtype=float)
        if x.shape != y.shape or x.ndim != 1 or x.size < 2:
            raise ParameterError(
                f"{_name(j, p)}: chainage_m and level_mm must be 1-D arrays of the same length >= 2"
            )
        if np.any(np.diff(x) <= 0):
            raise ParameterError(f"{_name(j, p)}: chainage_m must increase")
        try:
            f = np.broadcast_to(np.asarray(p.force_n, dtype=float), x.shape)
        except ValueError:
            raise ParameterError(
                f"{_name(j, p)}: force_n must be a number of N or one value "
                f"per chainage point ({x.size}), got shape {np.shape(p.force_n)}"
            ) from None
        if np.any(np.isfinite(f) & (f <= 0)):
            raise ParameterError(f"{_name(j, p)}: wheel force must be > 0 N (compression)")
        ok = np.isfinite(y) & np.isfinite(f)
        if ok.sum() < 2:
            continue
        inside = (grid >= x[ok][0]) & (grid <= x[ok][-1])
        # a gap inside the pass stays a gap: interpolate the validity too
        valid = np.interp(grid, x, ok.astype(float)) > 0.999
        sel = inside & valid
        levels[j, sel] = np.interp(grid[sel], x[ok], y[ok])
        forces[j, sel] = np.interp(grid[sel], x[ok], f[ok])
    return grid, levels, forces
