"""A track's separated geometry and support stiffness, kept up to date as passes come and go.

Every merged run (reference or aligned) keeps its loaded level *and* the wheel force under it
on the track grid (``track_run_levels``); every reference survey its level at a known wheel
load (``survey_levels``). ``engine.separation.separate`` turns these passes into the unloaded
geometry, the compliance and ``k/k_nom`` per grid point, and soft spots.

When it runs: in the transaction that adds or removes a pass (after the aggregate, under the
track lock) — for a run stored by the background worker, in the worker's next transaction
instead (``app.services.track.integrate.separate_pending``: the run is done without waiting) — for
the chunks the pass covers plus :data:`MARGIN_CHUNKS` of context either side; the result is
stored per chunk (``track_stiffness``) and soft spots by their peak
(``track_stiffness_spots``). Reads are then one indexed range scan and no numerics: a 2 km
window reads in milliseconds whatever the number of runs, while the separation costs the writer
what the engine needs for the stretch it touched (50 runs over 10 km: about 2 s). Computing on
read (a cache keyed by a version counter) would put that cost on the first reader of every
window after each upload instead.

Units: chainage in m (aligned), levels and geometry in mm, forces in N, compliance in mm/kN,
``k_rel`` dimensionless (1 = nominal).
"""

from __future__ import annotations

import dataclasses
import logging
import math
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray
from sqlalchemy import delete, insert, select, update
from sqlalchemy.orm import Session

from app.db.models import (
    Run,
    Survey,
    SurveyLevels,
    Track,
    TrackRunLevels,
    TrackStiffness,
    TrackStiffnessSpot,
    Vehicle,
    VehicleVersion,
)
from app.services.storage.packing import unpack_f4_kept
from app.services.storage.profiles import finite_or_none
from app.services.track.aggregate import CHUNK_POINTS, newest_runs
from app.services.track.alignment import GRID_STEP_M
from app.services.track.separation_history import record_separation
from app.services.track.separation_trust import TRUSTED, Trust, judge, run_bases
from app.services.views.notation import km_m, km_m_range
from engine.end_rings import EndRingShapes, end_ring_shapes, ring_speed_mps
from engine.errors import EngineError
from engine.separation import (
    NOT_SEPARABLE_MESSAGE,
    Pass,
    SeparationConfig,
    SeparationResult,
    load_limited,
    separate,
)
from engine.track import TrackParams
from engine.vehicle_kinds import per_wheel, vehicle_from_dict

STIFFNESS_ARRAYS = (
    "geometry_mm",
    "geometry_sd_mm",
    "k_rel",
    "k_rel_lo",
    "k_rel_hi",
    "compliance_mm_per_kn",
    "n_passes",
    "load_ratio",
    "separable",
)
"""Per-point results stored per chunk (float32 each; ``separable`` as 0/1)."""

MARGIN_CHUNKS = 1
"""Chunks of context read either side of a recomputed stretch (250 m: far more than the
reach of the rail's bending, so a chunk's result does not depend on where a batch ends)."""

BATCH_CHUNKS = 40
"""Chunks separated at once (10 km)."""

NOT_SEPARABLE = NOT_SEPARABLE_MESSAGE
"""What is said wherever the passes cannot tell rail geometry from support stiffness."""

UPDATING = (
    "the separation is being redone over part of this window after a run stored a moment "
    "ago: what follows is the state before that run; read again in a few seconds"
)
"""What is said while a window's separation waits (``StiffnessWindow.updating``)."""

_DTYPE = np.dtype("<f4")

log = logging.getLogger(__name__)


def run_stiffness_basis(single_pass_valid: bool | None) -> tuple[str | None, str | None]:
    """What a run's own stiffness-loss figures rest on, and the message when they are withheld.

    ``("single pass", None)`` when the engine found the rail smooth at the noise level (one
    pass can tell stiffness); ``("not separable", NOT_SEPARABLE)`` when geometry could have
    made its dips; ``(None, None)`` for runs processed before the check existed.
    """
    if single_pass_valid is None:
        return None, None
    if single_pass_valid:
        return "single pass", None
    return "not separable", NOT_SEPARABLE


@dataclass(frozen=True)
class PassLevels:
    """One pass (run or survey) over a stretch of the track grid (levels mm, force N)."""

    kind: str
    id: int
    level_mm: NDArray[np.float64]
    force_n: NDArray[np.float64]
    wheel_offsets_m: tuple[float, ...] = (0.0,)
    """The wheels sharing ``force_n`` about the measured point, m (a bogie's two; a survey's
    and a half car's axle: one)."""
    end_rings: EndRingShapes | None = None
    """The run's vehicle's ring shapes at its speed (none for a survey)."""

    @property
    def label(self) -> str:
        """``run 12`` or ``survey 3``: how the pass is named where it contributed."""
        return f"{self.kind} {self.id}"


def _unblob(blob: bytes) -> NDArray[np.float64]:
    return unpack_f4_kept(blob)


def read_passes(session: Session, track_id: int, c_lo: int, c_hi: int) -> list[PassLevels]:
    """Every pass with data in chunks ``c_lo..c_hi``, on their grid (chunk ``c_lo`` first):
    every survey, and each chunk's newest runs (``app.services.track.aggregate.newest_runs``).

    Runs stored before wheel forces were kept (``force_n`` NULL) are left out: without a
    force they cannot take part in the separation.
    """
    n = (c_hi - c_lo + 1) * CHUNK_POINTS
    passes: dict[tuple[str, int], tuple[NDArray[np.float64], NDArray[np.float64]]] = {}

    def slot(kind: str, pid: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        if (kind, pid) not in passes:
            passes[kind, pid] = (np.full(n, np.nan), np.full(n, np.nan))
        return passes[kind, pid]

    t = TrackRunLevels.__table__
    keys = newest_runs(track_id, c_lo, c_hi, with_force=True)
    for rid, chunk, levels, force in session.execute(
        select(t.c.run_id, t.c.chunk, t.c.levels, t.c.force_n).join(
            keys, (keys.c.run_id == t.c.run_id) & (keys.c.chunk == t.c.chunk)
        )
    ):
        lv, fv = slot("run", int(rid))
        at = (chunk - c_lo) * CHUNK_POINTS
        lv[at : at + CHUNK_POINTS] = _unblob(levels)
        fv[at : at + CHUNK_POINTS] = _unblob(force)
    s = SurveyLevels.__table__
    for sid, chunk, levels, load in session.execute(
        select(s.c.survey_id, s.c.chunk, s.c.levels, Survey.wheel_load_n)
        .join(Survey, Survey.id == s.c.survey_id)
        .where(s.c.track_id == track_id, s.c.chunk >= c_lo, s.c.chunk <= c_hi)
    ):
        lv, fv = slot("survey", int(sid))
        at = (chunk - c_lo) * CHUNK_POINTS
        part = _unblob(levels)
        lv[at : at + CHUNK_POINTS] = part
        fv[at : at + CHUNK_POINTS] = np.where(np.isfinite(part), float(load), np.nan)
    # the end rings are fitted across passes: one pass alone needs no shapes
    vehicles = _run_vehicles(
        session, [pid for kind, pid in passes if kind == "run"], rings=len(passes) >= 2
    )
    out = []
    for (kind, pid), (lv, fv) in sorted(passes.items()):
        # A wheel force that is not a compression (a pass stored under a vehicle that was not
        # plausible) cannot be separated: its points are left out, not the whole stretch, so
        # that removing any pass (a run deleted, a vehicle restored) always succeeds.
        with np.errstate(invalid="ignore"):
            fv[~(fv > 0)] = np.nan
        fv[~np.isfinite(lv)] = np.nan
        lv[~np.isfinite(fv)] = np.nan
        if np.isfinite(lv).any():
            # a survey: a point load, and a level with no inversion's ring
            one, rings = vehicles.get(pid, ((0.0,), None)) if kind == "run" else ((0.0,), None)
            out.append(PassLevels(kind, pid, lv, fv, one, rings))
    return out


def _run_vehicles(
    session: Session, run_ids: list[int], *, rings: bool = True
) -> dict[int, tuple[tuple[float, ...], EndRingShapes | None]]:
    """Each run's wheels about its measured point (m) and, with ``rings``, its vehicle's end
    ring shapes at the run's speed, from the vehicle version that made its results (the
    vehicle's current parameters where that version is not stored). Shapes that cannot be
    made leave the run's level as it is (its ends weighed as without them)."""
    if not run_ids:
        return {}
    rows = session.execute(
        select(Run.id, Run.vehicle_version, Run.speed_min_mps, Run.speed_max_mps, Vehicle)
        .join(Vehicle, Vehicle.id == Run.vehicle_id)
        .where(Run.id.in_(run_ids))
    ).all()
    versions = {
        (vid, ver): prm
        for vid, ver, prm in session.execute(
            select(VehicleVersion.vehicle_id, VehicleVersion.version, VehicleVersion.params).where(
                VehicleVersion.vehicle_id.in_({v.id for *_, v in rows})
            )
        )
    }
    out: dict[int, tuple[tuple[float, ...], EndRingShapes | None]] = {}
    for rid, ver, v_lo, v_hi, veh in rows:
        prm = versions.get((veh.id, ver if ver is not None else veh.version), veh.params_dict())
        vehicle = vehicle_from_dict(prm)
        shapes: EndRingShapes | None = None
        try:
            if rings:
                shapes = end_ring_shapes(vehicle, ring_speed_mps(v_lo, v_hi))
        except (EngineError, ValueError):
            log.warning("no end ring shapes for run %s", rid, exc_info=True)
        out[int(rid)] = (tuple(vehicle.axle_wheel_offsets_m[0]), shapes)
    return out


def _batches(c_lo: int, c_hi: int) -> Iterator[tuple[int, int]]:
    for a in range(c_lo, c_hi + 1, BATCH_CHUNKS):
        yield a, min(c_hi, a + BATCH_CHUNKS - 1)


def _on_grid(
    res: SeparationResult, name: str, i0: int, n: int, fill: float = np.nan
) -> NDArray[np.float64]:
    # The engine answers on its own grid (normally ours): place its values by chainage.
    out = np.full(n, fill)
    x = np.asarray(res.chainage_m, dtype=np.float64)
    v = np.asarray(getattr(res, name), dtype=np.float64)
    if v.ndim == 0:
        v = np.full(x.shape, float(v))
    idx = np.rint(x / GRID_STEP_M).astype(np.int64) - i0
    ok = (idx >= 0) & (idx < n)
    out[idx[ok]] = v[ok]
    return out


def _contributors(passes: list[PassLevels], lo: int, hi: int) -> list[dict[str, Any]]:
    out = []
    for p in passes:
        f = p.force_n[lo:hi]
        ok = np.isfinite(f)
        if ok.any():
            out.append({
                "kind": p.kind, "id": p.id, "label": p.label,
                "mean_force_n": float(f[ok].mean()), "points": int(ok.sum()),
            })  # fmt: skip
    return out


def _chunk_rows(
    track_id: int, res: SeparationResult, passes: list[PassLevels], a: int, b: int, r_lo: int,
    n: int,
) -> tuple[list[dict[str, Any]], int]:  # fmt: skip
    """The ``track_stiffness`` rows of chunks ``a..b`` from a separation over the ``n`` grid
    points from chunk ``r_lo`` on, and the number of grid points they cover."""
    cols = {name: _on_grid(res, name, r_lo * CHUNK_POINTS, n) for name in STIFFNESS_ARRAYS}
    cols["n_passes"] = np.nan_to_num(cols["n_passes"], nan=0.0)
    rows = []
    written = 0
    for chunk in range(a, b + 1):
        lo = (chunk - r_lo) * CHUNK_POINTS
        hi = lo + CHUNK_POINTS
        if not (cols["n_passes"][lo:hi] > 0).any():
            continue
        data = b"".join(
            np.asarray(cols[name][lo:hi], dtype=_DTYPE).tobytes() for name in STIFFNESS_ARRAYS
        )
        contributors = _contributors(passes, lo, hi)
        covered = cols["n_passes"][lo:hi] > 0
        rows.append({
            "track_id": track_id, "chunk": chunk, "data": data,
            "meta": {"contributors": contributors},
        })  # fmt: skip
        written += int(covered.sum())
    return rows, written


def _spot_rows(
    track_id: int, res: SeparationResult, passes: list[PassLevels], grid: NDArray[np.float64],
    x_lo: float, x_hi: float,
) -> list[dict[str, Any]]:  # fmt: skip
    """The ``track_stiffness_spots`` rows of the soft spots peaking in ``[x_lo, x_hi)``, m."""
    return [
        {
            "track_id": track_id,
            "start_m": float(sp.start_m),
            "end_m": float(sp.end_m),
            "peak_m": float(sp.peak_m),
            "loss_pct": float(sp.loss_pct),
            "loss_lo_pct": finite_or_none(sp.loss_lo_pct),
            "loss_hi_pct": finite_or_none(sp.loss_hi_pct),
            "confidence": finite_or_none(sp.confidence),
            "depth_mm": finite_or_none(sp.depth_mm),
            "support": _support(passes, grid, sp.start_m, sp.end_m),
        }  # fmt: skip
        for sp in res.soft_spots
        if x_lo <= float(sp.peak_m) < x_hi and math.isfinite(float(sp.loss_pct))
    ]


def recompute_stiffness(session: Session, track_id: int, c_lo: int, c_hi: int) -> int:
    """Separate geometry and stiffness again over chunks ``c_lo..c_hi`` (caller's transaction).

    Reads the passes of those chunks and :data:`MARGIN_CHUNKS` either side, runs the engine's
    separation, rewrites the chunks' rows and the soft spots peaking in them. Returns the
    number of grid points with a result.
    """
    track = session.get(Track, track_id)
    if track is None:
        return 0
    params = TrackParams.from_dict(track.params_dict())
    written = 0
    for a, b in _batches(c_lo, c_hi):
        r_lo, r_hi = a - MARGIN_CHUNKS, b + MARGIN_CHUNKS
        x_lo, x_hi = a * CHUNK_POINTS * GRID_STEP_M, (b + 1) * CHUNK_POINTS * GRID_STEP_M
        session.execute(
            delete(TrackStiffness).where(
                TrackStiffness.track_id == track_id,
                TrackStiffness.chunk >= a,
                TrackStiffness.chunk <= b,
            )
        )
        session.execute(
            delete(TrackStiffnessSpot).where(
                TrackStiffnessSpot.track_id == track_id,
                TrackStiffnessSpot.peak_m >= x_lo,
                TrackStiffnessSpot.peak_m < x_hi,
            )
        )
        passes = read_passes(session, track_id, r_lo, r_hi)
        if not passes:
            continue
        i0 = r_lo * CHUNK_POINTS
        n = (r_hi - r_lo + 1) * CHUNK_POINTS
        grid = (i0 + np.arange(n, dtype=np.float64)) * GRID_STEP_M
        try:
            res = separate(
                [
                    Pass(chainage_m=grid, level_mm=p.level_mm, force_n=p.force_n, kind=p.kind,
                         label=p.label, wheel_offsets_m=p.wheel_offsets_m, end_rings=p.end_rings)
                    for p in passes
                ],
                params,
            )  # fmt: skip
        except EngineError:
            # the stretch is left without a separation rather than failing the change that
            # asked for it (a run's delete, a store): the next change there tries again
            log.warning("separation of track %s chunks %d-%d failed", track_id, a, b,
                        exc_info=True)  # fmt: skip
            continue
        rows, covered = _chunk_rows(track_id, res, passes, a, b, r_lo, n)
        written += covered
        if rows:
            session.execute(insert(TrackStiffness), rows)
        spots = _spot_rows(track_id, res, passes, grid, x_lo, x_hi)
        if spots:
            session.execute(insert(TrackStiffnessSpot), spots)
            record_separation(session, track_id, spots)
    return written


def _support(
    passes: list[PassLevels], grid: NDArray[np.float64], start_m: float, end_m: float
) -> list[dict[str, Any]]:
    """The passes with a level over ``[start_m, end_m]`` and their mean force per wheel there
    (N): a bogie's and a half car's of one wheel load are one load."""
    lo, hi = (int(i) for i in np.searchsorted(grid, [start_m, end_m + 1e-9]))
    out = []
    for p in passes:
        f = p.force_n[lo:hi]
        ok = np.isfinite(f)
        if ok.any():
            load = per_wheel(float(f[ok].mean()), p.wheel_offsets_m)
            out.append({"kind": p.kind, "id": p.id, "force_n": round(load, 1)})
    return out


def pending_chunks(session: Session, track_id: int) -> tuple[int, int] | None:
    """The chunks (first, last) whose separation waits for a worker after a run was stored
    (``app.services.track.integrate.separate_pending``); None when it is up to date."""
    row = session.execute(
        select(Track.separation_pending_lo, Track.separation_pending_hi).where(Track.id == track_id)
    ).one_or_none()
    if row is None or row[0] is None or row[1] is None:
        return None
    return int(row[0]), int(row[1])


def clear_pending(session: Session, track_id: int) -> None:
    """Mark the track's separation up to date (caller holds the track's lock)."""
    session.execute(
        update(Track)
        .where(Track.id == track_id)
        .values(separation_pending_lo=None, separation_pending_hi=None)
    )


def recompute_all(session: Session, track_id: int) -> int:
    """Separate a whole track again (after a realignment); grid points with a result."""
    bounds: list[int] = []
    for table in (TrackRunLevels.__table__, SurveyLevels.__table__):
        for (chunk,) in session.execute(
            select(table.c.chunk).where(table.c.track_id == track_id).distinct()
        ):
            bounds.append(int(chunk))
    session.execute(delete(TrackStiffness).where(TrackStiffness.track_id == track_id))
    session.execute(delete(TrackStiffnessSpot).where(TrackStiffnessSpot.track_id == track_id))
    if not bounds:
        return 0
    return recompute_stiffness(session, track_id, min(bounds), max(bounds))


@dataclass(frozen=True)
class StiffnessWindow:
    """The stored separation over a chainage window (see :func:`read_stiffness`).

    ``columns`` maps ``chainage_m`` and each of :data:`STIFFNESS_ARRAYS` to lists (None where
    not estimated; ``k_rel`` and its band None wherever the point is not separable);
    ``spots`` the separated soft spots peaking in the window; ``contributors`` the passes
    that reached it; ``message`` the plain-words reason where it could not separate.
    """

    columns: dict[str, list[Any]]
    spots: list[TrackStiffnessSpot]
    contributors: list[dict[str, Any]]
    message: str | None
    updating: bool = False
    """A run stored just now changed the window's passes and its separation is being redone
    (``app.services.track.integrate.separate_pending``): what is read is the state before it."""
    not_separable: list[Stretch] = dataclasses.field(default_factory=list)
    """Where the window is not separable, and why (``message`` says it in words)."""
    trust: Trust = TRUSTED
    """Whether the window's separation is provisional (a contributing vehicle neither
    calibrated nor with its runs' loads declared), as :func:`stiffness_with_vehicles` tells."""
    spot_trust: tuple[Trust, ...] = ()
    """The same for each of ``spots`` (empty where not told: every spot trusted)."""

    @property
    def n(self) -> int:
        """Grid points in the window with at least one pass."""
        return len(self.columns["chainage_m"])

    @property
    def separable(self) -> bool:
        """True when some covered point of the window is separable."""
        return any(self.columns["separable"])

    @property
    def separable_fraction(self) -> float:
        """Share of the window's covered points that are separable (0 when none is covered)."""
        sep = self.columns["separable"]
        return sum(sep) / len(sep) if sep else 0.0


def _none_nan(a: NDArray[np.float64]) -> list[float | None]:
    values: list[float | None] = a.tolist()
    for i in np.flatnonzero(~np.isfinite(a)):
        values[i] = None
    return values


def _spots_in(
    session: Session, track_id: int, from_m: float | None, to_m: float | None
) -> list[TrackStiffnessSpot]:
    """The separation's soft spots overlapping ``[from_m, to_m]`` (m), by start."""
    sp = TrackStiffnessSpot
    spot_stmt = select(sp).where(sp.track_id == track_id)
    if from_m is not None:
        spot_stmt = spot_stmt.where(sp.end_m >= from_m)
    if to_m is not None:
        spot_stmt = spot_stmt.where(sp.start_m <= to_m)
    return list(session.scalars(spot_stmt.order_by(sp.start_m)).all())


def _updating(session: Session, track_id: int, from_m: float | None, to_m: float | None) -> bool:
    """Whether chunks of the track overlapping ``[from_m, to_m]`` (m) wait for their
    separation to be redone."""
    pending = pending_chunks(session, track_id)
    return (
        pending is not None
        and (from_m is None or (pending[1] + 1) * CHUNK_POINTS * GRID_STEP_M > from_m)
        and (to_m is None or pending[0] * CHUNK_POINTS * GRID_STEP_M <= to_m)
    )


def read_stiffness(
    session: Session, track_id: int, from_m: float | None = None, to_m: float | None = None
) -> StiffnessWindow:
    """The track's separated geometry and stiffness between two chainages (m, inclusive).

    Only grid points some pass covers are listed. Where a point is not separable the
    stiffness (``k_rel``, its band, the compliance) and the geometry are None: one load
    cannot tell them apart, so no figure is given that geometry could have produced.
    """
    t = TrackStiffness.__table__
    stmt = select(t.c.chunk, t.c.data, t.c.meta).where(t.c.track_id == track_id)
    if from_m is not None:
        stmt = stmt.where(t.c.chunk >= math.floor(from_m / GRID_STEP_M) // CHUNK_POINTS)
    if to_m is not None:
        stmt = stmt.where(t.c.chunk <= math.floor(to_m / GRID_STEP_M) // CHUNK_POINTS)
    rows = session.execute(stmt.order_by(t.c.chunk)).all()
    k = len(STIFFNESS_ARRAYS)
    parts: list[NDArray[np.float64]] = []
    chainage: list[NDArray[np.float64]] = []
    contributors: dict[tuple[str, int], dict[str, Any]] = {}
    for chunk, data, meta in rows:
        block = np.frombuffer(data, dtype=_DTYPE).reshape(k, CHUNK_POINTS).astype(np.float64)
        x = (chunk * CHUNK_POINTS + np.arange(CHUNK_POINTS)) * GRID_STEP_M
        keep = block[STIFFNESS_ARRAYS.index("n_passes")] > 0
        if from_m is not None:
            keep &= x >= from_m - 1e-9
        if to_m is not None:
            keep &= x <= to_m + 1e-9
        if not keep.any():
            continue
        parts.append(block[:, keep])
        chainage.append(x[keep])
        for c in meta.get("contributors", []):
            key = (c["kind"], c["id"])
            if key not in contributors:
                contributors[key] = {**c, "force_sum": 0.0, "points": 0}
            contributors[key]["force_sum"] += c["mean_force_n"] * c["points"]
            contributors[key]["points"] += c["points"]
    if parts:
        block = np.concatenate(parts, axis=1)
        x = np.concatenate(chainage)
    else:
        block = np.empty((k, 0))
        x = np.empty(0)
    named = dict(zip(STIFFNESS_ARRAYS, block, strict=True))
    separable = named["separable"] > 0.5
    for name in ("k_rel", "k_rel_lo", "k_rel_hi", "compliance_mm_per_kn", "geometry_mm",
                 "geometry_sd_mm"):  # fmt: skip
        named[name] = np.where(separable, named[name], np.nan)
    columns: dict[str, list[Any]] = {"chainage_m": x.tolist()}
    for name in STIFFNESS_ARRAYS:
        if name == "separable":
            columns[name] = separable.tolist()
        elif name == "n_passes":
            columns[name] = named[name].astype(np.int64).tolist()
        else:
            columns[name] = _none_nan(named[name])
    spots = _spots_in(session, track_id, from_m, to_m)
    contrib = [
        {k2: v for k2, v in c.items() if k2 not in ("force_sum", "mean_force_n")}
        | {"mean_force_n": c["force_sum"] / max(1, c["points"])}
        for c in contributors.values()
    ]
    updating = _updating(session, track_id, from_m, to_m)
    stretches = not_separable_stretches(x, named["n_passes"], named["load_ratio"], separable)
    return StiffnessWindow(
        columns, spots, contrib, stretches_message(stretches) if x.size else None, updating,
        stretches,
    )  # fmt: skip


@dataclass(frozen=True)
class Stretch:
    """A stretch (aligned m, inclusive) where geometry and stiffness are not separable, and why:
    ``load`` (the passes there lack a second wheel load) or ``precision`` (their levels are too
    uncertain: near the ends of runs, or too few passes)."""

    from_m: float
    to_m: float
    reason: str

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict."""
        return {"from_m": self.from_m, "to_m": self.to_m, "reason": self.reason}


def not_separable_stretches(
    x: NDArray[np.float64],
    n_passes: NDArray[np.float64],
    load_ratio: NDArray[np.float64],
    separable: NDArray[np.bool_],
) -> list[Stretch]:
    """The covered stretches that are not separable, each with its reason (see :class:`Stretch`);
    a gap in the coverage or a change of reason starts a new one."""
    lacking = (n_passes > 0) & ~separable
    if not lacking.any():
        return []
    load = load_limited(n_passes, load_ratio)
    out: list[Stretch] = []
    idx = np.flatnonzero(lacking)
    start = prev = int(idx[0])
    for i in [*idx[1:].tolist(), None]:
        if (
            i is not None
            and x[i] - x[prev] <= GRID_STEP_M * 1.5
            and bool(load[i]) == bool(load[start])
        ):
            prev = i
            continue
        out.append(Stretch(float(x[start]), float(x[prev]), "load" if load[start] else "precision"))
        if i is not None:
            start = prev = i
    return out


_REMEDY = {
    "load": (
        "the passes there have one wheel load; a pass with a wheel load at least "
        "{pct:.0f} % different, or a survey, would separate them"
    ),
    "precision": (
        "the passes' levels there are too uncertain (near the ends of runs, or too few "
        "passes); more passes over them would separate them"
    ),
}


def stretches_message(stretches: list[Stretch]) -> str | None:
    """Where geometry and stiffness are not separable and what would make them separable, as
    sentences with chainages in km+m; None where the separation holds everywhere."""
    if not stretches:
        return None
    pct = 100.0 * (SeparationConfig().min_load_ratio - 1.0)
    parts = []
    for reason in ("load", "precision"):
        mine = [s for s in stretches if s.reason == reason]
        if not mine:
            continue
        where = ", ".join(
            km_m(s.from_m) if s.to_m - s.from_m < GRID_STEP_M else km_m_range(s.from_m, s.to_m)
            for s in mine[:6]
        )
        if len(mine) > 6:
            where += f" and {len(mine) - 6} more stretches"
        parts.append(
            f"Geometry and stiffness are not separable at {where}: "
            + _REMEDY[reason].format(pct=pct)
            + "."
        )
    return " ".join(parts)


def separable_intervals(session: Session, track_id: int) -> list[tuple[float, float]]:
    """Stretches (aligned m, inclusive) where the track's separation holds, in order.

    A stretch is a maximal run of separable grid points some pass covers, broken where a
    point is not separable or where no pass covers the grid (a gap). Only the ``separable``
    and ``n_passes`` rows of each stored chunk are decoded: the register asks for this on
    every request, over the whole line.
    """
    t = TrackStiffness.__table__
    rows = session.execute(
        select(t.c.chunk, t.c.data).where(t.c.track_id == track_id).order_by(t.c.chunk)
    ).all()
    k = len(STIFFNESS_ARRAYS)
    i_sep, i_n = STIFFNESS_ARRAYS.index("separable"), STIFFNESS_ARRAYS.index("n_passes")
    xs: list[NDArray[np.float64]] = []
    seps: list[NDArray[np.bool_]] = []
    for chunk, data in rows:
        block = np.frombuffer(data, dtype=_DTYPE).reshape(k, CHUNK_POINTS)
        keep = block[i_n] > 0
        if keep.any():
            x = (chunk * CHUNK_POINTS + np.arange(CHUNK_POINTS)) * GRID_STEP_M
            xs.append(x[keep])
            seps.append(block[i_sep][keep] > 0.5)
    if not xs:
        return []
    x = np.concatenate(xs)
    sep = np.concatenate(seps)
    # a break after point i: the next covered point is not separable, or not the next one
    brk = np.ones(x.size, dtype=bool)
    brk[:-1] = ~sep[1:] | (np.diff(x) > GRID_STEP_M * 1.5)
    starts = np.flatnonzero(sep & np.concatenate(([True], brk[:-1] | ~sep[:-1])))
    ends = np.flatnonzero(sep & brk)
    return [(float(x[a]), float(x[b])) for a, b in zip(starts, ends, strict=True)]


def spot_support(session: Session, spot: TrackStiffnessSpot) -> list[dict[str, Any]]:
    """The passes behind a separated soft spot (``{"kind", "id", "force_n"}``): its stored
    ``support``, or for a spot stored before that was kept, the passes of its chunk."""
    if spot.support is not None:
        return list(spot.support)
    chunk = math.floor(spot.peak_m / GRID_STEP_M) // CHUNK_POINTS
    meta = session.scalar(
        select(TrackStiffness.meta).where(
            TrackStiffness.track_id == spot.track_id, TrackStiffness.chunk == chunk
        )
    )
    return [
        {"kind": c["kind"], "id": c["id"], "force_n": c.get("mean_force_n")}
        for c in (meta or {}).get("contributors", [])
    ]


def stiffness_with_vehicles(
    session: Session, track_id: int, from_m: float | None = None, to_m: float | None = None
) -> StiffnessWindow:
    """:func:`read_stiffness` with each contributing run's vehicle name (``vehicle``), and
    whether each soft spot and the window (where some point of it is separable) are
    provisional (:func:`app.services.track.separation_trust.trust_of`)."""
    window = read_stiffness(session, track_id, from_m, to_m)
    if not window.spots and not any(c["kind"] == "run" for c in window.contributors):
        return window  # surveys alone: known loads, no vehicle to name or doubt
    bases = run_bases(session, track_id)
    contributors = [
        c | {"vehicle": bases[c["id"]].vehicle if c["id"] in bases else None}
        if c["kind"] == "run" else c | {"vehicle": None}
        for c in window.contributors
    ]  # fmt: skip
    of = judge(bases)
    spot_trust = tuple(
        of((p["kind"], p["id"]) for p in spot_support(session, sp)) for sp in window.spots
    )
    return dataclasses.replace(
        window,
        contributors=contributors,
        # nothing separated, nothing to trust or doubt: the message says what is missing
        trust=of((c["kind"], c["id"]) for c in window.contributors)
        if window.separable
        else TRUSTED,
        spot_trust=spot_trust,
    )
