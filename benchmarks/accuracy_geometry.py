"""Accuracy of the geometry/stiffness separation. Updates docs/accuracy.md.

Run: ``python benchmarks/accuracy_geometry.py [--tracks 2] [--out docs/accuracy.md] [--no-rings]``
(about 3 minutes per track on 2 cores).

Every case uses the engine's own forward model with fixed seeds: a 600 m track with German
low-disturbance geometry (unless the irregularity level is the variable), support stiffness
scattered +-5 %, three soft zones of 4-10 m with 35-50 % loss at random places in 130-470 m,
runs at 20-28 m/s simulated at 500 Hz with the shared samples' sensor noise per sample (bias
0.02 m/s² / 2e-4 rad/s, noise 0.005 m/s² / 1e-4 rad/s), logged start chainages off by up to
+-2 m. Each run is processed from its logged start (``process_run``), the passes are aligned
to one another (``align_passes``) and separated (``separate``). A zone counts as found when a
reported soft spot overlaps it; edges and losses are for the zones found; a false zone is a
reported spot that overlaps no true zone. Geometry: RMS of (estimated - true) unloaded level
in the 3-25 m band over the separable stretch.

Variables: the load ratio (3 table1 runs and 2 runs of a vehicle whose body is heavier so
that its wheel load is 1.2, 1.5 or 2 x table1's; 2.2 x is the heavy preset), the number of
runs (half table1, half heavy) and the irregularity level (German low x 0.5, x 1, German
high).
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

import numpy as np  # noqa: E402
from common import machine, publish_section  # noqa: E402

from engine.chainage import bandpass_distance  # noqa: E402
from engine.end_rings import end_ring_shapes, run_speed_mps  # noqa: E402
from engine.pipeline import process_run  # noqa: E402
from engine.separation import align_passes, pass_from_result, separate  # noqa: E402
from engine.setup import RunSetup, prepare_run
from engine.synthetic import REALISTIC_SENSOR, SyntheticRun, make_run, make_track  # noqa: E402
from engine.track import SoftZone  # noqa: E402
from engine.vehicle import HEAVY, TABLE1, VehicleParams  # noqa: E402

START = "<!-- geometry-accuracy:start -->"
END = "<!-- geometry-accuracy:end -->"
RATE = 500.0
RINGS = True
"""The passes carry their end ring shapes (``--no-rings``: they do not)."""
SENSOR = dataclasses.replace(REALISTIC_SENSOR, sample_rate_hz=RATE)


def loaded(ratio: float) -> VehicleParams:
    """Table 1 with a heavier body, so that its mean static wheel load is ``ratio`` x table1's."""
    mu = 0.5 * (TABLE1.mu1 + TABLE1.mu2)
    scale = (ratio * (0.5 * TABLE1.ms + mu) - mu) / (0.5 * TABLE1.ms)
    return dataclasses.replace(TABLE1, ms=TABLE1.ms * scale, Is=TABLE1.Is * scale)


class Case:
    """One track and a cache of processed runs over it, by (vehicle name, index)."""

    def __init__(self, seed: int, irregularity: str = "german-low", scale: float = 1.0) -> None:
        rng = np.random.default_rng(seed)
        zones = []
        x = float(rng.uniform(130, 160))
        for _ in range(3):
            ln = float(rng.choice([4.2, 6.0, 7.8, 9.6]))
            zones.append(SoftZone(round(x / 0.6) * 0.6, round((x + ln) / 0.6) * 0.6,
                                  round(float(rng.uniform(0.35, 0.5)), 2)))  # fmt: skip
            x += ln + float(rng.uniform(90, 120))
        self.zones = tuple(zones)
        self.seed = seed
        self.track = make_track(600.0, zones=zones, jitter=0.05, irregularity=irregularity,
                                irregularity_scale=scale, seed=seed)  # fmt: skip
        self.rng = rng
        self.runs: dict[tuple[str, int], tuple[SyntheticRun, object]] = {}

    def run(self, name: str, vehicle: VehicleParams, i: int):
        key = (name, i)
        if key not in self.runs:
            # a stable seed per (track, vehicle, index): str hashes change between processes
            r = np.random.default_rng([self.seed, sum(map(ord, name)), i])
            speed, err = float(r.uniform(20, 28)), float(r.uniform(-2, 2))
            syn = make_run(track=self.track, vehicle=vehicle, speed=speed, sensor=SENSOR,
                           sim_rate_hz=RATE, seed=1000 * self.seed + 10 * i,
                           start_chainage_m=12.0, start_error_m=err)  # fmt: skip
            res = process_run(
                prepare_run(
                    syn.log, RunSetup(start_chainage_m=syn.logged_start_chainage_m, vehicle=vehicle)
                )
            )
            self.runs[key] = (syn, res)
        return self.runs[key]


def score(case: Case, picks: list[tuple[str, VehicleParams, int]]) -> dict[str, float]:
    """Separate the picked runs of a case and compare with its truth."""
    got = [case.run(n, v, i) for n, v, i in picks]
    passes = [
        pass_from_result(
            res,
            label=f"{n}{i}",
            end_rings=end_ring_shapes(v, run_speed_mps(res)) if RINGS else None,
        )
        for (n, v, i), (_, res) in zip(picks, got, strict=True)
    ]
    aligned, offsets = align_passes(passes)
    sep = separate(aligned)
    errors = [syn.logged_start_chainage_m - syn.start_chainage_m for syn, _ in got]
    frame = float(np.mean(errors))  # aligned chainage = true + mean logged error
    found, edge, loss, false = 0, 0.0, 0.0, 0
    g = sep.chainage_m
    inside = 0
    for z in case.zones:
        span = (g >= z.start_m + frame - 1.0) & (g <= z.end_m + frame + 1.0)
        inside += int(span.any() and sep.separable[span].all())
    for z in case.zones:
        hits = [s for s in sep.soft_spots
                if s.end_m - frame >= z.start_m and s.start_m - frame <= z.end_m]  # fmt: skip
        if hits:
            s = hits[0]
            found += 1
            edge = max(edge, abs(s.start_m - frame - z.start_m), abs(s.end_m - frame - z.end_m))
            loss = max(loss, abs(s.loss_pct - 100 * z.loss))
    for s in sep.soft_spots:
        if not any(s.end_m - frame >= z.start_m and s.start_m - frame <= z.end_m
                   for z in case.zones):  # fmt: skip
            false += 1
    ok = sep.separable
    rms = float("nan")
    if ok.sum() > 400:
        truth = got[0][0].true_geometry(g - frame)
        est = bandpass_distance(np.where(ok, sep.geometry_mm, np.nan), 0.25, 3.0, 25.0)
        ref = bandpass_distance(np.where(ok, truth, np.nan), 0.25, 3.0, 25.0)
        m = np.isfinite(est) & np.isfinite(ref)
        m &= (g > g[m][0] + 10) & (g < g[m][-1] - 10)
        rms = float(np.sqrt(np.mean((est[m] - ref[m]) ** 2)))
    covered = sep.n_passes > 0
    return {
        "found": found, "true": len(case.zones), "inside": inside, "false": false,
        "edge": edge, "loss": loss,
        "rms": rms, "sep": float(sep.separable[covered].mean()),
    }  # fmt: skip


def combine(rows: list[dict[str, float]]) -> dict[str, float]:
    return {
        "found": sum(r["found"] for r in rows), "true": sum(r["true"] for r in rows),
        "inside": sum(r["inside"] for r in rows),
        "false": sum(r["false"] for r in rows), "edge": max(r["edge"] for r in rows),
        "loss": max(r["loss"] for r in rows),
        "rms": max((r["rms"] for r in rows if np.isfinite(r["rms"])), default=float("nan")),
        "sep": float(np.mean([r["sep"] for r in rows])),
    }  # fmt: skip


def line(label: str, r: dict[str, float]) -> str:
    rms = "—" if not np.isfinite(r["rms"]) else f"{r['rms']:.3f}"
    edge = f"{r['edge']:.2f}" if r["found"] else "—"
    loss = f"{r['loss']:.1f}" if r["found"] else "—"
    return (f"| {label} | {r['found']}/{r['true']} | {r['inside']} | {r['false']} | {edge} | "
            f"{loss} | {rms} | "
            f"{100 * r['sep']:.0f} % |")  # fmt: skip


HEADER = [
    "| case | zones found | zones inside the separable stretch | false zones | "
    "worst edge error, m | worst loss error, pp | geometry error 3-25 m, mm RMS (worst) | "
    "separable share of the covered track |",
    "|---|---|---|---|---|---|---|---|",
]


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--out", default=str(Path(__file__).resolve().parents[1] / "docs/accuracy.md"))
    p.add_argument("--tracks", type=int, default=2, help="tracks (seeds) per case")
    p.add_argument(
        "--no-rings",
        action="store_true",
        help="the passes without their end rings (the separation before them)",
    )
    ns = p.parse_args()
    global RINGS
    RINGS = not ns.no_rings
    t0 = time.perf_counter()
    seeds = [101 + 17 * k for k in range(ns.tracks)]
    cases = [Case(s) for s in seeds]
    t1 = [("t", TABLE1, i) for i in range(3)]
    ratio_rows = []
    for ratio in (1.2, 1.5, 2.0):
        veh = loaded(ratio)
        rows = [score(c, t1 + [(f"x{ratio}", veh, i) for i in range(2)]) for c in cases]
        ratio_rows.append(line(f"3 table1 + 2 at {ratio:g}x load", combine(rows)))
    veh = loaded(1.2)
    t5 = [("t", TABLE1, i) for i in range(5)]
    rows = [score(c, t5 + [("x1.2", veh, i) for i in range(5)]) for c in cases]
    ratio_rows.append(line("5 table1 + 5 at 1.2x load", combine(rows)))
    rows = [score(c, t1 + [("h", HEAVY, i) for i in range(2)]) for c in cases]
    ratio_rows.append(line("3 table1 + 2 heavy (2.2x)", combine(rows)))
    rows = [score(c, [("t", TABLE1, i) for i in range(5)]) for c in cases]
    ratio_rows.append(line("5 table1 (1x: one vehicle type)", combine(rows)))
    count_rows = []
    for n_light, n_heavy in ((1, 1), (2, 1), (3, 2), (5, 5)):
        picks = [("t", TABLE1, i) for i in range(n_light)] + [
            ("h", HEAVY, i) for i in range(n_heavy)
        ]
        rows = [score(c, picks) for c in cases]
        count_rows.append(line(f"{n_light + n_heavy} runs ({n_light} table1 + {n_heavy} heavy)",
                               combine(rows)))  # fmt: skip
    irr_rows = []
    for spec, scale, label in (("german-low", 0.5, "German low x 0.5 (≈ 0.5 mm in 3-25 m)"),
                               ("german-low", 1.0, "German low (≈ 1.0 mm)"),
                               ("german-high", 1.0, "German high (≈ 1.7 mm)")):  # fmt: skip
        cs = (
            cases if (spec, scale) == ("german-low", 1.0) else [Case(s, spec, scale) for s in seeds]
        )
        picks = t1 + [("h", HEAVY, i) for i in range(2)]
        irr_rows.append(line(label, combine([score(c, picks) for c in cs])))
    elapsed = time.perf_counter() - t0
    zones = "; ".join(
        ", ".join(f"{z.start_m:g}-{z.end_m:g} m {100 * z.loss:.0f} %" for z in c.zones)
        for c in cases
    )
    section = [
        START,
        "## Geometry and stiffness separated across runs (issue 10)",
        "",
        f"Generated by `python benchmarks/accuracy_geometry.py --tracks {ns.tracks}` "
        f"({elapsed / 60:.0f} min; do not edit by hand). Machine: {machine()}.",
        "",
        "600 m tracks with German low-disturbance geometry (unless varied), supports "
        "scattered ±5 %, three soft zones each (" + zones + "), runs at 20-28 m/s with the "
        "fibre-optic grade's sensor noise and bias (the shared samples'), logged starts off "
        "by up to ±2 m, aligned to "
        "one another and separated (`engine/separation.py`). Counts are summed and errors "
        f"are the worst over {ns.tracks} tracks. Targets (issue 10): every zone, ends "
        "±1.5 m, loss ±10 pp, no false zone, geometry ≤ 0.15 mm RMS. A zone outside the "
        "separable stretch (too little load spread, or near the runs' ends where the "
        "inversion's edge error dominates, after their rings are fitted: "
        "`engine/end_rings.py`) gets no figure: that stretch carries the not-separable "
        "message instead.",
        "",
        "### Against the load ratio",
        "",
        *HEADER,
        *ratio_rows,
        "",
        "### Against the number of runs",
        "",
        *HEADER,
        *count_rows,
        "",
        "### Against the irregularity level (3 table1 + 2 heavy)",
        "",
        *HEADER,
        *irr_rows,
        "",
        "Single pass on the same tracks: the rail is not smooth at the noise level "
        "(`ProcessResult.geometry_check`), so a run alone reports dips without a "
        "stiffness-loss figure.",
        END,
    ]
    publish_section(section, Path(ns.out))


if __name__ == "__main__":
    main()
