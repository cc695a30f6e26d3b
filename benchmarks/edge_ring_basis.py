"""Is a pass's end error a few shapes, and does the difference of two passes find them? (issue 32)

Run: ``python benchmarks/edge_ring_basis.py [--seeds 9101-9103] [--test-seeds 9104-9105]
[--k 6] [--peer] [--sensitivity] [--timing] [--cases b43,...,d8300]
[--free-seeds 8200-8209] [--no-pairs]`` (about 6 min on 2 cores the first time; the runs are cached,
:func:`benchmarks.common.cached`).

A measurement, not a product path. A pass's level rings over its first and last ~100 m
(docs/method.md "Edges of a pass"): the log lacks the body's response to the rail before its
first sample and after its last. The error is linear in what is missing, so this asks:

1. **How many shapes?** Per vehicle (the bogie coach at 28 m/s, the freight wagon at 18 m/s,
   true vehicles, MEMS at 500 Hz, German-low rail, 5 % scatter) a 1100 m log is processed whole
   and cut into 300 m logs starting every 45 m from 150 m in. The first and last 120 m of each
   cut's level minus the whole log's there is one sample of the start and the end error. The
   share of held-out samples' energy (the last third) left outside the first ``k`` singular
   vectors of the others, over 0-120 m and at 40-100 m from the end.
2. **Does the pair find them?** On other seeds a coach and a wagon pass over the same rail,
   both cut at the same place. Their levels' difference is fitted, robustly, with the two
   passes' start and end shapes (``k`` each, anchored at each pass's own first and last level
   sample); RMS of the difference's error (against the whole logs' difference) band-passed
   3-40 m as the separation sees it, before and after, by distance to the nearer end.
3. **What it costs a zone**: the share of a 3.6 m and a 7.2 m soft-spot dip in the difference
   that the fit leaves, by the zone's distance to the start.
4. ``--peer``: the public ROSE pair (coach 24 m/s, wagon 18 m/s): the shapes made with this
   engine's model of the peer's vehicles (from their datasheets) at the peer's speeds, fitted
   on the peer pair's difference; error against the truth's difference (the peer's levels
   under each vehicle, band-passed on the whole track) before and after; and the separation of
   the pair, corrected or not, at ``edge_factor`` 0.3 (default), 0.15, 0.08 and 0.04.
5. ``--cases`` / ``--free-seeds``: the engine's own bogie cases (``accuracy_bogie_separation``'s
   named cases, ``d<seed>`` drawn with zones) and zone-free drawn tracks
   (``separation_false_alarms``) through the product's separation: without the passes' end
   rings (edge factor 0.3, as before them, and 0.08) and with them (the engine's shapes,
   ``engine.end_rings``: the product's default); zones found and false spots.
6. ``--sensitivity``: the last seed's errors against shapes from the first seed alone, from
   other speeds, from a vehicle 10 % heavier; the half car's own shapes.
7. ``--timing``: the separation's CPU time with and without the rings (``--cases``' named
   cases, b43, s7 and s11 without).
"""

from __future__ import annotations

import argparse
import dataclasses
import itertools
import sys
from dataclasses import replace
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numpy as np  # noqa: E402
from numpy.typing import NDArray  # noqa: E402

from benchmarks.common import cached  # noqa: E402
from benchmarks.edge_error import bp, cut_log, process  # noqa: E402
from engine.bogie import FREIGHT_WAGON, PASSENGER_COACH  # noqa: E402
from engine.passes import Pass  # noqa: E402
from engine.synthetic import REALISTIC_SENSOR, make_run, make_track  # noqa: E402
from engine.vehicle_kinds import Vehicle  # noqa: E402

SPAN_M = 120.0
TAPER_M = 30.0
EDGE_FACTORS = (0.3, 0.15, 0.08)
CUT_LEN_M = 300.0
TRACK_M = 1100.0
BINS_M = ((0.0, 25.0), (25.0, 50.0), (50.0, 75.0), (75.0, 100.0), (100.0, 150.0))
SENSOR = dataclasses.replace(REALISTIC_SENSOR, sample_rate_hz=500.0)
OWN = {"coach": (PASSENGER_COACH, 28.0), "wagon": (FREIGHT_WAGON, 18.0)}

Array = NDArray[np.float64]


def seeds_arg(text: str) -> list[int]:
    a, _, b = text.partition("-")
    return list(range(int(a), int(b or a) + 1))


def rms(x: Array) -> float:
    return float(np.sqrt(np.mean(x**2))) if x.size else float("nan")


def simulate(vehicle: Vehicle, speed: float, seed: int, salt: int = 1000):  # type: ignore[no-untyped-def]
    track = make_track(TRACK_M, jitter=0.05, irregularity="german-low", seed=seed)
    return make_run(track=track, vehicle=vehicle, speed=speed, sensor=SENSOR, sim_rate_hz=500.0,
                    seed=seed + salt, start_chainage_m=12.0)  # fmt: skip


def cut_level(run, whole, vehicle: Vehicle, speed: float, c0: float) -> Array:  # type: ignore[no-untyped-def]
    """The level of the 300 m log cut ``c0`` m after the log's start, on the whole's grid."""
    t0 = c0 / speed
    part = process(
        cut_log(run.log, t0, t0 + CUT_LEN_M / speed), run.start_chainage_m + speed * t0, vehicle
    )
    return np.asarray(np.interp(whole.chainage_m, part.chainage_m, part.level_mm, np.nan, np.nan))


def end_errors(vehicle: Vehicle, speed: float, seeds: list[int]) -> tuple[Array, Array, float]:
    """Start and end error samples (rows, mm, ``SPAN_M`` long from the cut's first / up to
    its last level sample) and the grid step (m)."""

    def make() -> tuple[Array, Array, float]:
        starts, ends = [], []
        step = 0.0
        for seed in seeds:
            run = simulate(vehicle, speed, seed)
            whole = process(run.log, run.start_chainage_m, vehicle)
            step = float(whole.chainage_m[1] - whole.chainage_m[0])
            n = int(round(SPAN_M / step))
            for c0 in np.arange(150.0, TRACK_M - CUT_LEN_M - 150.0, 45.0):
                lvl = cut_level(run, whole, vehicle, speed, float(c0))
                idx = np.flatnonzero(np.isfinite(lvl))
                err = lvl - whole.level_mm
                starts.append(err[idx[0] : idx[0] + n])
                ends.append(err[idx[-1] - n + 1 : idx[-1] + 1])
        return np.array(starts), np.array(ends), step

    out: tuple[Array, Array, float] = cached(
        "edge_ring", f"errors|{vehicle!r}|{speed}|{seeds}|{SPAN_M}|{CUT_LEN_M}", make
    )
    return out


def shapes(rows: Array, k: int) -> Array:
    """The first ``k`` right singular vectors of ``rows`` (k, n)."""
    return np.asarray(np.linalg.svd(rows, full_matrices=False)[2][:k])


def held_out_left(rows: Array, ks: tuple[int, ...], step: float) -> list[tuple[int, float, float]]:
    """Energy share of the last third of ``rows`` outside the first ``k`` shapes of the rest:
    over the whole span and at 40-100 m."""
    n_train = rows.shape[0] * 2 // 3
    test = rows[n_train:]
    seg = slice(int(40 / step), int(100 / step))
    out = []
    for k in ks:
        b = shapes(rows[:n_train], k)
        left = test - (test @ b.T) @ b
        out.append(
            (
                k,
                float(np.sum(left**2) / np.sum(test**2)),
                float(np.sum(left[:, seg] ** 2) / np.sum(test[:, seg] ** 2)),
            )
        )
    return out


def columns(
    shape_rows: Array, shape_step: float, grid_n: int, step: float, anchor: int, at_end: bool
) -> Array:
    """``shape_rows`` placed on a grid of ``grid_n`` points of ``step`` m, starting at index
    ``anchor`` (a start shape) or ending there (an end shape); zero elsewhere. (k, grid_n)."""
    xs = np.arange(shape_rows.shape[1]) * shape_step
    xg = (np.arange(grid_n) - anchor) * step + (xs[-1] if at_end else 0.0)
    inside = (xg >= 0) & (xg <= xs[-1])
    out = np.zeros((shape_rows.shape[0], grid_n))
    # tapered to zero over the span's far 30 m: a shape cut off there would leave a step
    far = xg[inside] if at_end else xs[-1] - xg[inside]
    fade = np.clip(far / TAPER_M, 0.0, 1.0)
    fade = 0.5 - 0.5 * np.cos(np.pi * fade)
    for i, row in enumerate(shape_rows):
        out[i, inside] = np.interp(xg[inside], xs, row) * fade
    return out


def robust_fit(a: Array, y: Array, iters: int = 8) -> Array:
    """Huber-weighted least squares of ``y`` on the columns of ``a`` (a zone's dip is an
    outlier to shapes tens of metres long)."""
    w = np.ones_like(y)
    coef = np.zeros(a.shape[1])
    for _ in range(iters):
        coef = np.linalg.lstsq(a * w[:, None], y * w, rcond=None)[0]
        r = y - a @ coef
        s = 1.4826 * float(np.median(np.abs(r - np.median(r))))
        w = np.sqrt(np.minimum(1.0, 1.5 * s / np.maximum(np.abs(r), 1e-12)))
    return np.asarray(coef)


def pass_columns(
    levels: list[Array], bases: list[tuple[Array, Array, float]], step: float
) -> list[Array]:
    """Per pass its start and end shapes as columns on the common grid (n, 2k), anchored at
    the pass's own first and last level sample."""
    out = []
    for v, (start, end, sstep) in zip(levels, bases, strict=True):
        idx = np.flatnonzero(np.isfinite(v))
        n = v.size
        out.append(
            np.vstack(
                [
                    columns(start, sstep, n, step, int(idx[0]), False),
                    columns(end, sstep, n, step, int(idx[-1]), True),
                ]
            ).T
        )
    return out


def fit_rings(
    levels: list[Array], bases: list[tuple[Array, Array, float]], step: float
) -> list[Array]:
    """Each pass's fitted ring (mm on the common grid): the shapes of every pass fitted at
    once, robustly, to the differences of every pair of passes where both have a level. What
    the passes share (the rail, a ring common to all) cancels in the differences and stays."""
    cols = pass_columns(levels, bases, step)
    m = cols[0].shape[1]
    rows, ys = [], []
    for j, k in itertools.combinations(range(len(levels)), 2):
        ok = np.isfinite(levels[j]) & np.isfinite(levels[k])
        a = np.zeros((int(ok.sum()), m * len(levels)))
        a[:, j * m : (j + 1) * m] = cols[j][ok]
        a[:, k * m : (k + 1) * m] = -cols[k][ok]
        rows.append(a)
        ys.append((levels[j] - levels[k])[ok])
    coef = robust_fit(np.vstack(rows), np.concatenate(ys))
    return [cols[j] @ coef[j * m : (j + 1) * m] for j in range(len(levels))]


def fitted_passes(passes: list[Pass], bases: list[tuple[Array, Array, float]]) -> list[Pass]:
    """The passes with their fitted rings taken off their levels."""
    step = float(passes[0].chainage_m[1] - passes[0].chainage_m[0])
    x0 = min(float(p.chainage_m[0]) for p in passes)
    x1 = max(float(p.chainage_m[-1]) for p in passes)
    grid = np.arange(x0, x1 + step / 2, step)
    lv = [np.interp(grid, p.chainage_m, p.level_mm, np.nan, np.nan) for p in passes]
    rings = fit_rings(lv, bases, step)
    return [
        replace(p, level_mm=p.level_mm - np.interp(p.chainage_m, grid, r))
        for p, r in zip(passes, rings, strict=True)
    ]


def by_distance(err: Array, step: float) -> list[float]:
    d = np.minimum(np.arange(err.size), err.size - 1 - np.arange(err.size)) * step
    return [rms(err[(d >= a) & (d < b)]) for a, b in BINS_M]


def own_pairs(k: int, train: list[int], test: list[int]) -> list[str]:
    bases = {}
    lines = ["## 1. Shapes of the end error (held-out energy left outside the first k)", ""]
    lines += ["| vehicle | end | k | left, 0-120 m | left, 40-100 m |", "|---|---|---|---|---|"]
    for kind, (veh, v) in OWN.items():
        s, e, step = end_errors(veh, v, train)
        for name, rows in (("start", s), ("end", e)):
            for kk, left, mid in held_out_left(rows, (2, 4, 6, 8, 12), step):
                lines.append(f"| {kind} | {name} | {kk} | {left:.3f} | {mid:.3f} |")
        bases[kind] = (shapes(s, k), shapes(e, k), step)
    a_s, a_w = bases["coach"][0], bases["wagon"][0]
    cos = np.linalg.svd(a_s @ a_w.T, compute_uv=False)
    lines += ["", f"Cosines of the principal angles between the coach's and the wagon's {k} start "
              f"shapes: {', '.join(f'{c:.3f}' for c in cos)}.", ""]  # fmt: skip

    def make() -> list[tuple[list[float], list[float]]]:
        out = []
        for seed in test:
            runs = {}
            for j, (kind, (veh, v)) in enumerate(OWN.items()):
                run = simulate(veh, v, seed, salt=1000 * (j + 1))
                runs[kind] = (run, process(run.log, run.start_chainage_m, veh), veh, v)
            grid = runs["coach"][1].chainage_m
            step = float(grid[1] - grid[0])
            whole = [np.interp(grid, r[1].chainage_m, r[1].level_mm) for r in runs.values()]
            for c0 in map(float, np.arange(150.0, TRACK_M - CUT_LEN_M - 150.0, 60.0)):
                lv = []
                for run, res, veh, v in runs.values():
                    # NaN outside the cut's coverage stays NaN through the interpolation
                    lv.append(np.interp(grid, res.chainage_m, cut_level(run, res, veh, v, c0)))
                both = np.isfinite(lv[0]) & np.isfinite(lv[1])
                i0, i1 = np.flatnonzero(both)[[0, -1]]
                seg = slice(i0, i1 + 1)
                rings = fit_rings(lv, [bases["coach"], bases["wagon"]], step)
                diff = (lv[0] - lv[1])[seg]
                ref = (whole[0] - whole[1])[seg]
                out.append(
                    (
                        by_distance(bp(diff - ref, step), step),
                        by_distance(bp(diff - (rings[0] - rings[1])[seg] - ref, step), step),
                    )
                )
        return out

    rows = cached("edge_ring", f"pairs|{k}|{train}|{test}|{SPAN_M}", make)
    before = np.sqrt(np.nanmean(np.array([r[0] for r in rows]) ** 2, axis=0))
    after = np.sqrt(np.nanmean(np.array([r[1] for r in rows]) ** 2, axis=0))
    head = " | ".join(f"{a:.0f}-{b:.0f} m" for a, b in BINS_M)
    lines += [
        f"## 2. Coach and wagon cut at the same place, seeds {test[0]}-{test[-1]} "
        f"({len(rows)} pairs): RMS of the difference's error in 3-40 m (mm) by distance to "
        "the nearer end",
        "",
        f"| | {head} |",
        "|---" * (len(BINS_M) + 1) + "|",
        "| as processed | " + " | ".join(f"{x:.3f}" for x in before) + " |",
        f"| {k} start + {k} end shapes per pass fitted on the difference | "
        + " | ".join(f"{x:.3f}" for x in after)
        + " |",
        "",
    ]
    lines += dip_lines(bases, step)
    return lines


def dip_lines(bases: dict[str, tuple[Array, Array, float]], step: float) -> list[str]:
    n = int(round(2 * SPAN_M / step)) + 200
    cols = pass_columns([np.zeros(n), np.zeros(n)], [bases["coach"], bases["wagon"]], step)
    a = np.hstack([cols[0], -cols[1]])
    proj = a @ np.linalg.pinv(a)  # the least-squares fit of the difference (no outlier weights)
    x = np.arange(n) * step
    lines = ["## 3. Share of a zone's dip (3-40 m) left after the fit, by its centre's distance "
             "to the start", "", "| zone length | 10 m | 20 m | 30 m | 40 m | 56 m | 70 m | 90 m |",
             "|---|---|---|---|---|---|---|---|"]  # fmt: skip
    box = max(1, int(2.5 / step))
    for length in (3.6, 7.2):
        cells = []
        for c in (10, 20, 30, 40, 56, 70, 90):
            dip = -0.5 * (np.abs(x - c) < length / 2)
            dip = np.convolve(dip, np.ones(box) / box, mode="same")  # a bogie's spread
            kept = bp(dip - proj @ dip, step)
            ref = bp(dip, step)
            near = np.abs(x - c) < length
            cells.append(f"{kept[near].min() / ref[near].min():.2f}")
        lines.append(f"| {length} m | " + " | ".join(cells) + " |")
    return lines + [""]


def peer_lines(k: int, train: list[int]) -> list[str]:
    from benchmarks.accuracy_peer_bogie import default_dir, process_one, truth_level
    from benchmarks.peer_truth import zones_as_built
    from engine.passes import align_passes, pass_from_result
    from engine.separation import SeparationConfig, separate

    d = default_dir()
    csvs = [d / "pub_coach_irr.csv", d / "pub_freight_irr.csv"]
    done = [process_one(c, "bogie") for c in csvs]
    bases = []
    for _res, veh, truth, _ in done:
        s, e, sstep = end_errors(veh, float(truth["speed"]), train)
        bases.append((shapes(s, k), shapes(e, k), sstep))
    passes = [
        pass_from_result(res, label=c.stem, wheel_offsets_m=veh.axle_wheel_offsets_m[0])
        for c, (res, veh, _, _) in zip(csvs, done, strict=True)
    ]
    passes, _ = align_passes(passes)
    grid = passes[0].chainage_m
    step = float(grid[1] - grid[0])
    lv = [np.interp(grid, p.chainage_m, p.level_mm, np.nan, np.nan) for p in passes]
    truth = [
        truth_level(dict(np.load(c.with_suffix(".truth.npz"))), grid, p.wheel_offsets_m)
        for c, p in zip(csvs, passes, strict=True)
    ]
    both = np.isfinite(lv[0]) & np.isfinite(lv[1])
    i0, i1 = np.flatnonzero(both)[[0, -1]]
    seg = slice(i0, i1 + 1)
    rings = fit_rings(lv, bases, step)
    diff = (lv[0] - lv[1])[seg]
    ref = (truth[0] - truth[1])[seg]
    before = by_distance(bp(diff - ref, step), step)
    after = by_distance(bp(diff - (rings[0] - rings[1])[seg] - ref, step), step)
    head = " | ".join(f"{lo:.0f}-{hi:.0f} m" for lo, hi in BINS_M)
    lines = [
        "## 4. The public ROSE pair, shapes from this engine's model of its vehicles",
        "",
        f"RMS of the pass difference's error against the truth's (3-40 m, mm), by distance to "
        f"the nearer end of the common coverage ({grid[i0]:.0f}-{grid[i1]:.0f} m):",
        "",
        f"| | {head} |",
        "|---" * (len(BINS_M) + 1) + "|",
        "| as processed | " + " | ".join(f"{x:.3f}" for x in before) + " |",
        "| fitted | " + " | ".join(f"{x:.3f}" for x in after) + " |",
        "",
    ]
    fixed = [
        replace(p, level_mm=p.level_mm - np.interp(p.chainage_m, grid, r))
        for p, r in zip(passes, rings, strict=True)
    ]
    zones = zones_as_built(done[0][2], dict(np.load(csvs[0].with_suffix(".truth.npz"))))
    lines += [
        "Zones as built: "
        + "; ".join(
            f"{z['start_m']:.1f}-{z['end_m']:.1f} m {100 * z['stiffness_loss']:.0f} %"
            for z in zones
        ),
        "",
        "| edge_factor | levels | separable | soft spots (start-end m, loss %) |",
        "|---|---|---|---|",
    ]
    for ef in EDGE_FACTORS + (0.04,):
        for label, ps in (("as processed", passes), ("fitted", fixed)):
            sep = separate(ps, config=SeparationConfig(edge_factor=ef))
            cov = sep.n_passes > 0
            spots = "; ".join(
                f"{s.start_m:.1f}-{s.end_m:.1f} {s.loss_pct:.0f}" for s in sep.soft_spots
            )
            lines.append(
                f"| {ef} | {label} | {100 * sep.separable[cov].mean():.0f} % | {spots or '—'} |"
            )
    return lines + [""]


def case_lines(names: list[str], free: list[int]) -> list[str]:
    """The engine's own bogie cases (named, ``d<seed>`` drawn with zones) and zone-free drawn
    tracks through the product's separation: the passes without their end rings at the
    default edge term (the separation before the rings) and at ``edge_factor`` 0.08, and with
    the engine's ring shapes (:func:`engine.end_rings.end_ring_shapes`, fitted by
    ``separate``: the product now)."""
    from benchmarks.accuracy_bogie_separation import CASES, drawn, passes_of, score
    from benchmarks.separation_false_alarms import drawn_case
    from engine.separation import SeparationConfig, separate

    jobs = [(n, CASES[n] if n in CASES else drawn(n)) for n in names]
    jobs += [(f"free {seed}", drawn_case(seed)) for seed in free]
    variants = (
        ("no rings, edge 0.3", False, SeparationConfig()),
        ("no rings, edge 0.08", False, SeparationConfig(edge_factor=0.08)),
        ("rings fitted (default)", True, SeparationConfig()),
    )
    totals: dict[tuple[str, str], list[int]] = {}
    lines = [
        "## 5. The engine's own bogie cases: zones found / zones, false spots",
        "",
        "| case | vehicles | " + " | ".join(v[0] for v in variants) + " |",
        "|---|---|" + "---|" * len(variants),
    ]
    for name, case in jobs:
        for label, passes in passes_of(case).items():
            cells = []
            for vname, rings, cfg in variants:
                ps = passes if rings else [replace(p, end_rings=None) for p in passes]
                sc = score(separate(ps, config=cfg), case.zones)
                t = totals.setdefault((label, vname), [0, 0, 0])
                t[0] += sc["found"]
                t[1] += len(case.zones)
                t[2] += len(sc["false"])
                cells.append(
                    f"{sc['found']}/{len(case.zones)}"
                    + (f", false {', '.join(sc['false'])}" if sc["false"] else "")
                )
            lines.append(f"| {name} | {label} | " + " | ".join(cells) + " |")
    lines += ["", "| vehicles | " + " | ".join(v[0] for v in variants) + " |",
              "|---|" + "---|" * len(variants)]  # fmt: skip
    for label in ("registered presets", "true vehicles"):
        cells = []
        for vname, _, _ in variants:
            f, n, fa = totals.get((label, vname), [0, 0, 0])
            cells.append(f"{f}/{n} found, {fa} false")
        lines.append(f"| {label} | " + " | ".join(cells) + " |")
    return lines + [""]


def sensitivity_lines(k: int, train: list[int]) -> list[str]:
    """How much the shapes depend on what makes them: energy of the last seed's start and
    end errors left outside shapes made from the first seed alone, at another speed, for a
    vehicle 10 % heavier; and the half car's own shapes (held out as in section 1)."""
    from engine.synthetic import TABLE1

    lines = [
        "## 6. What the shapes depend on: energy left outside them (start; end), "
        "0-120 m and 40-100 m",
        "",
        "| errors of | shapes from | start | end |",
        "|---|---|---|---|",
    ]

    def left(rows: Array, b: Array, step: float) -> str:
        r = rows - (rows @ b.T) @ b
        seg = slice(int(40 / step), int(100 / step))
        whole = np.sum(r**2) / np.sum(rows**2)
        mid = np.sum(r[:, seg] ** 2) / np.sum(rows[:, seg] ** 2)
        return f"{whole:.4f}, {mid:.4f}"

    for kind, (veh, v0) in OWN.items():
        s0, e0, step = end_errors(veh, v0, train)
        third = s0.shape[0] // len(train)
        ts, te = s0[-third:], e0[-third:]
        variants = [(f"seed {train[0]} alone", s0[:third], e0[:third])]
        for dv in (-2.0, -1.0, 1.0, 2.0):
            s1, e1, _ = end_errors(veh, v0 + dv, train)
            variants.append((f"{v0 + dv:.0f} m/s", s1, e1))
        heavy = veh.replace(body_mass_kg=1.1 * veh.body_mass_kg)
        s2, e2, _ = end_errors(heavy, v0, train)
        variants.append(("a body 10 % heavier", s2, e2))
        for label, s1, e1 in variants:
            lines.append(
                f"| {kind} {v0:.0f} m/s, seed {train[-1]} | {label} | "
                f"{left(ts, shapes(s1, k), step)} | {left(te, shapes(e1, k), step)} |"
            )
    s3, e3, step = end_errors(TABLE1, 22.0, train)
    n_train = s3.shape[0] * 2 // 3
    lines.append(
        f"| half car TABLE1 22 m/s, held-out third | the other cuts | "
        f"{left(s3[n_train:], shapes(s3[:n_train], k), step)} | "
        f"{left(e3[n_train:], shapes(e3[:n_train], k), step)} |"
    )
    return lines + [""]


def timing_lines(names: list[str]) -> list[str]:
    """CPU time of ``separate`` on the named cases' passes with and without their end rings
    (three interleaved rounds; the shapes already made: they are made once per process)."""
    import time

    from benchmarks.accuracy_bogie_separation import CASES, passes_of
    from engine.separation import separate

    sets = []
    for name in names:
        for passes in passes_of(CASES[name]).values():
            sets.append((passes, [replace(p, end_rings=None) for p in passes]))
    without = with_rings = 0.0
    for _ in range(3):
        for passes, bare in sets:
            t = time.process_time()
            separate(bare)
            without += time.process_time() - t
            t = time.process_time()
            separate(passes)
            with_rings += time.process_time() - t
    n = 3 * len(sets)
    return [
        "## 7. CPU time of the separation (4 passes, 500-600 m)",
        "",
        f"{len(sets)} separations, 3 rounds: without the rings {1e3 * without / n:.0f} ms each, "
        f"with them {1e3 * with_rings / n:.0f} ms (x{with_rings / without:.2f}).",
        "",
    ]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="9101-9103", help="seeds whose cuts give the shapes")
    ap.add_argument("--test-seeds", default="9104-9105", help="seeds of the coach+wagon pairs")
    ap.add_argument("--k", type=int, default=6, help="shapes per end and pass")
    ap.add_argument("--peer", action="store_true", help="also the public ROSE pair")
    ap.add_argument("--cases", default="", help="own bogie cases, e.g. b43,s7,d5000")
    ap.add_argument("--free-seeds", default="", help="zone-free drawn tracks, e.g. 8200-8209")
    ap.add_argument("--no-pairs", action="store_true", help="skip sections 1-3")
    ap.add_argument("--sensitivity", action="store_true", help="what the shapes depend on")
    ap.add_argument("--timing", action="store_true", help="the separation's CPU time")
    args = ap.parse_args()
    train, test = seeds_arg(args.seeds), seeds_arg(args.test_seeds)
    lines = [] if args.no_pairs else own_pairs(args.k, train, test)
    if args.peer:
        lines += peer_lines(args.k, train)
    if args.sensitivity:
        lines += sensitivity_lines(args.k, train)
    if args.timing:
        lines += timing_lines([n for n in args.cases.split(",") if n] or ["b43", "s7", "s11"])
    if args.cases or args.free_seeds:
        names = [n for n in args.cases.split(",") if n]
        free = seeds_arg(args.free_seeds) if args.free_seeds else []
        lines += case_lines(names, free)
    print("\n".join(lines))


if __name__ == "__main__":
    main()
