"""Accuracy on the peer's runs: bogie vehicles on a layered track made with ROSE.

Run: ``python benchmarks/accuracy_peer_bogie.py [--data DIR [DIR ...]] [--vehicle
bogie|lumped] [--separate [--truth-levels] [--compliance-every M] [--no-rings]]
[--ring-variants]``

Each run of each ``DIR`` (a CSV with its truth JSON and NPZ; default
``$SHARED_DIR/data/peer-bogie``, ``/work/shared`` without it; unseen runs from
``benchmarks/peer_runs/make_rose_runs.py``)
is processed as a user would upload it: the CSV, its start chainage and direction, and the
vehicle from its datasheet (``bogie``: the whole-vehicle values of the truth JSON as a
:class:`engine.bogie.BogieParams`; ``lumped``: the README's lumped half car). Nothing of the
truth but the vehicle, the start chainage and the direction enters the processing.

Scored as the README's section 5 says: a zone is found when a reported soft spot overlaps it
with both ends within 1.5 m; a false zone overlaps no true zone widened by 1.5 m; loss error
in percentage points; the profile against the bogie-mean truth, band-passed 3-25 m and
3-40 m (4th-order zero-phase Butterworth in wavenumber, 25 m dropped at each end).

``--separate``: the rough-rail runs (coach and wagon) together through the separation, each
pass with its vehicle's wheels (``engine.separation.separate``), aligned as the service
aligns them; scored the same way, plus the share of covered points that is separable.
With several folders (one track each), each is separated on its own and the zones found and
false zones are summed over them at the end.

``--ring-variants``: the same separations with other settings of the passes' end-ring fit
(:data:`RING_VARIANTS`: fewer or more shapes, a tighter or looser prior, longer shapes), zones
found and false zones per folder side by side.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from dataclasses import replace
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numpy as np  # noqa: E402
from numpy.typing import NDArray  # noqa: E402

from benchmarks.peer_truth import (  # noqa: E402
    FOUND_TOL_M,
    FOUND_TOL_PP,
    bogie_from_truth,
    bogie_mean_truth,
    butter_band,
    ends_within,
    zones_as_built,
)
from engine.chainage import bandpass_distance  # noqa: E402
from engine.end_rings import EndRingConfig, end_ring_shapes, run_speed_mps  # noqa: E402
from engine.logio.parse import read_run_csv  # noqa: E402
from engine.passes import align_passes, pass_from_result  # noqa: E402
from engine.pipeline import process_run  # noqa: E402
from engine.results import ProcessResult  # noqa: E402
from engine.separation import SeparationConfig, SeparationResult, separate  # noqa: E402
from engine.setup import RunSetup, prepare_run  # noqa: E402
from engine.vehicle import VehicleParams  # noqa: E402
from engine.vehicle_kinds import Vehicle  # noqa: E402

TOL_M = FOUND_TOL_M


def default_dir() -> Path:
    return Path(os.environ.get("SHARED_DIR", "/work/shared")) / "data" / "peer-bogie"


def lumped_from_truth(truth: dict) -> VehicleParams:
    """The README's lumped half car (each bogie one axle)."""
    h = truth["half_car_lumped"]
    keys = ("ms", "Is", "mu1", "mu2", "ks1", "ks2", "cs1", "cs2", "kt1", "kt2", "d1", "d2")
    return VehicleParams(**{k: h[k] for k in keys})


def profile_scores(res: ProcessResult, npz: dict) -> dict[str, float]:
    """RMS difference, truth RMS, correlation and gain in the 3-25 and 3-40 m bands."""
    x = res.chainage_m
    step = float(x[1] - x[0])
    truth = bogie_mean_truth(npz, x) * 1e3
    ok = np.isfinite(truth) & np.isfinite(res.level_mm)
    i0, i1 = np.flatnonzero(ok)[[0, -1]]
    seg = slice(i0, i1 + 1)
    out: dict[str, float] = {}
    for lo, hi in ((3.0, 25.0), (3.0, 40.0)):
        t = butter_band(truth[seg], step, lo, hi)
        m = butter_band(res.level_mm[seg], step, lo, hi)
        drop = int(round(25.0 / step))
        t, m = t[drop:-drop], m[drop:-drop]
        tag = f"{lo:g}-{hi:g}"
        out[f"rms_diff_{tag}"] = float(np.sqrt(np.mean((m - t) ** 2)))
        out[f"rms_truth_{tag}"] = float(np.sqrt(np.mean(t**2)))
        out[f"corr_{tag}"] = float(np.corrcoef(m, t)[0, 1])
        out[f"gain_{tag}"] = float(np.polyfit(t, m, 1)[0])
    return out


def zone_scores(res: ProcessResult, zones: list[dict]) -> dict[str, object]:
    """Per true zone: the matching spot's ends and loss; and the false spots."""
    rows = []
    for z in zones:
        hit = None
        for s in res.soft_spots:
            overlaps = s.start_m <= z["end_m"] and s.end_m >= z["start_m"]
            if overlaps and (
                hit is None or abs(s.start_m - z["start_m"]) < abs(hit.start_m - z["start_m"])
            ):
                hit = s
        row = {"true": (z["start_m"], z["end_m"], 100 * z["stiffness_loss"])}
        if hit is not None:
            d0, d1 = hit.start_m - z["start_m"], hit.end_m - z["end_m"]
            row |= {
                "found": ends_within(d0, d1),
                "reported": (hit.start_m, hit.end_m, hit.stiffness_loss_pct),
                "d_start": d0,
                "d_end": d1,
                "loss_err_pp": hit.stiffness_loss_pct - 100 * z["stiffness_loss"],
            }
        else:
            row |= {"found": False}
        rows.append(row)
    false = [
        (s.start_m, s.end_m)
        for s in res.soft_spots
        if not any(
            s.start_m <= z["end_m"] + TOL_M and s.end_m >= z["start_m"] - TOL_M for z in zones
        )
    ]
    return {"zones": rows, "false": false}


def process_one(csv: Path, vehicle_kind: str) -> tuple[ProcessResult, Vehicle, dict, float]:
    """The run processed as uploaded: result, vehicle, truth JSON, seconds."""
    truth = json.loads(csv.with_suffix(".truth.json").read_text())
    vehicle: Vehicle = (
        bogie_from_truth(truth) if vehicle_kind == "bogie" else lumped_from_truth(truth)
    )
    t0 = time.perf_counter()
    res = process_run(
        prepare_run(
            read_run_csv(csv),
            RunSetup(truth["start_chainage_m"], truth["direction"], vehicle),
        )
    )
    return res, vehicle, truth, time.perf_counter() - t0


def truth_level(npz: dict, grid: NDArray[np.float64], offsets: tuple[float, ...]) -> NDArray:
    """The truth a pass's level estimates, on ``grid`` (m), mm, band-passed 3-40 m as the
    product's: the rail geometry at the wheels' offsets (``irr``, known over the whole track,
    so no band edge at the pass's ends) plus the bogie-mean rail deflection (its mean
    outside the stretch both bogies cover)."""
    x = np.asarray(npz["irr_x"])
    g = np.mean([np.interp(x + o, x, npz["irr"]) for o in offsets], axis=0)
    disp = npz["rail_disp_wheels"]
    front = np.interp(x, npz["x_front_bogie"], 0.5 * (disp[0] + disp[1]), np.nan, np.nan)
    rear = np.interp(x, npz["x_rear_bogie"], 0.5 * (disp[2] + disp[3]), np.nan, np.nan)
    d = 0.5 * (front + rear)
    d = np.where(np.isfinite(d), d, np.nanmean(d))
    level = bandpass_distance((g + d) * 1e3, float(x[1] - x[0]), 3.0, 40.0)
    return np.asarray(np.interp(grid, x, level))


def separate_rough(
    csvs: list[Path],
    vehicle_kind: str,
    truth_levels: bool = False,
    every_m: float = 0.0,
    rings: bool = True,
    tally: list[int] | None = None,
    ring_config: EndRingConfig | None = None,
) -> list[str]:
    """The rough runs together through the separation: one line per true zone and a summary.
    ``truth_levels``: each pass's level replaced by its truth (the separation alone judged);
    ``every_m`` > 0: also the compliance excess every ``every_m`` m (:func:`compliance_lines`);
    ``tally``: ``[zones found, zones, false zones]``, added to; ``ring_config``: how the
    passes' end rings are made and fitted (default: the product's)."""
    done = [process_one(c, vehicle_kind) for c in csvs]
    passes = [
        pass_from_result(
            res, label=c.stem, wheel_offsets_m=veh.axle_wheel_offsets_m[0],
            end_rings=end_ring_shapes(veh, run_speed_mps(res), ring_config)
            if rings and not truth_levels
            else None,
        )
        for c, (res, veh, _, _) in zip(csvs, done, strict=True)
    ]  # fmt: skip
    if truth_levels:
        for j, c in enumerate(csvs):
            p = passes[j]
            t = truth_level(dict(np.load(c.with_suffix(".truth.npz"))), p.chainage_m,
                            p.wheel_offsets_m)  # fmt: skip
            passes[j] = replace(p, level_mm=np.where(np.isfinite(p.level_mm), t, np.nan))
    passes, offsets = align_passes(passes, recentre=not truth_levels)
    sep = separate(passes, config=SeparationConfig(end_rings=ring_config or EndRingConfig()))
    zones = zones_as_built(done[0][2], dict(np.load(csvs[0].with_suffix(".truth.npz"))))
    covered = sep.n_passes > 0
    lines = [
        f"Separation of {', '.join(c.stem for c in csvs)} (vehicle {vehicle_kind}"
        f"{'; TRUTH levels' if truth_levels else ''}); alignment "
        f"offsets {', '.join(f'{o:+.2f}' for o in offsets)} m; separable "
        f"{100 * sep.separable[covered].mean():.0f} % of the covered points "
        f"({sep.chainage_m[covered][0]:.0f}-{sep.chainage_m[covered][-1]:.0f} m).",
        "",
        "| zone (true) | separable there | reported | Δstart, Δend (m) | loss true → reported "
        "| found |",
        "|---|---|---|---|---|---|",
    ]
    found = 0
    for z in zones:
        inside = (sep.chainage_m >= z["start_m"]) & (sep.chainage_m <= z["end_m"])
        hit = [s for s in sep.soft_spots if s.start_m <= z["end_m"] and s.end_m >= z["start_m"]]
        loss = 100 * z["stiffness_loss"]
        if hit:
            d0, d1 = hit[0].start_m - z["start_m"], hit[0].end_m - z["end_m"]
            ok = ends_within(d0, d1) and abs(hit[0].loss_pct - loss) <= FOUND_TOL_PP
            found += ok
            rep = (
                f"{hit[0].start_m:.1f}-{hit[0].end_m:.1f} m | {d0:+.1f}, {d1:+.1f} | "
                f"{loss:.0f} → {hit[0].loss_pct:.0f} % | {'yes' if ok else 'no'}"
            )
        else:
            rep = f"— | — | {loss:.0f} → — | no"
        lines.append(
            f"| {z['start_m']:.1f}-{z['end_m']:.1f} m | "
            f"{100 * sep.separable[inside].mean():.0f} % | {rep} |"
        )
    false = [
        f"{s.start_m:.1f}-{s.end_m:.1f}"
        for s in sep.soft_spots
        if not any(
            s.start_m <= z["end_m"] + TOL_M and s.end_m >= z["start_m"] - TOL_M for z in zones
        )
    ]
    if tally is not None:
        tally[0] += found
        tally[1] += len(zones)
        tally[2] += len(false)
    lines += ["", f"False zones: {', '.join(false) or 'none'}. Message: {sep.message or 'none'}"]
    lines += resolution_lines(sep, zones)
    return lines + (compliance_lines(sep, every_m) if every_m else [])


RING_VARIANTS: dict[str, EndRingConfig] = {
    "product (6 shapes per end, prior 3x)": EndRingConfig(),
    "4 shapes": EndRingConfig(n_shapes=4),
    "8 shapes": EndRingConfig(n_shapes=8),
    "prior 1x (tighter)": EndRingConfig(prior_scale=1.0),
    "prior 10x (looser)": EndRingConfig(prior_scale=10.0),
    "span 160 m (fade 40 m, 400 m cuts)": EndRingConfig(
        span_m=160.0, fade_m=40.0, cut_m=400.0, rail_m=1300.0
    ),
}
"""The end-ring fits compared by ``--ring-variants`` (what the fit's settings do)."""


def ring_variant_lines(by_dir: list[list[Path]], vehicle_kind: str) -> list[str]:
    """Per :data:`RING_VARIANTS` setting, the zones found and false zones of each folder's
    rough runs separated together, and their sums."""
    names = [csvs[0].parent.name for csvs in by_dir]
    lines = [
        "| end-ring fit | " + " | ".join(names) + " | all |",
        "|---|" + "---|" * (len(names) + 1),
    ]
    for label, cfg in RING_VARIANTS.items():
        total, cells = [0, 0, 0], []
        for csvs in by_dir:
            tally = [0, 0, 0]
            rough = [c for c in csvs if c.stem.endswith("_irr")]
            separate_rough(rough, vehicle_kind, tally=tally, ring_config=cfg)
            total = [a + b for a, b in zip(total, tally, strict=True)]
            cells.append(f"{tally[0]}/{tally[1]}" + (f", {tally[2]} false" if tally[2] else ""))
        lines.append(f"| {label} | " + " | ".join(cells)
                     + f" | {total[0]}/{total[1]}, {total[2]} false |")  # fmt: skip
    return lines


def compliance_lines(sep: SeparationResult, every_m: float) -> list[str]:
    """The separated compliance over its median on the separable points, and its standard
    deviation, every ``every_m`` m (um/kN; '-' where not separable)."""
    x = sep.chainage_m
    c0 = float(np.nanmedian(sep.compliance_mm_per_kn[sep.separable]))
    out = ["", "| chainage (m) | compliance excess (um/kN) | sd (um/kN) |", "|---|---|---|"]
    for g in np.arange(np.ceil(x[0] / every_m) * every_m, x[-1], every_m):
        i = int(np.argmin(np.abs(x - g)))
        if sep.separable[i]:
            excess = 1e3 * (sep.compliance_mm_per_kn[i] - c0)
            out.append(f"| {g:.0f} | {excess:+.2f} | {1e3 * sep.compliance_sd_mm_per_kn[i]:.2f} |")
        else:
            out.append(f"| {g:.0f} | - | - |")
    return out


def resolution_lines(sep: SeparationResult, zones: list[dict]) -> list[str]:
    """What the pair could resolve: the smallest detectable loss away from the zones, and each
    zone's peak compliance excess over its standard deviation."""
    x = sep.chainage_m
    away = sep.separable.copy()
    for z in zones:
        away &= (x < z["start_m"] - 10.0) | (x > z["end_m"] + 10.0)
    if not away.any():
        return []
    c0 = float(np.nanmedian(sep.compliance_mm_per_kn[away]))
    parts = []
    for z in zones:
        inside = (x >= z["start_m"]) & (x <= z["end_m"]) & sep.separable
        if inside.any():
            excess = np.nanmax(sep.compliance_mm_per_kn[inside]) - c0
            sd = float(np.nanmean(sep.compliance_sd_mm_per_kn[inside]))
            parts.append(f"{z['start_m']:.1f}-{z['end_m']:.1f} m {excess / sd:.1f} sd")
    return [
        f"Smallest detectable loss away from the zones (median of 1 - k_rel_lo): "
        f"{100 * (1 - np.nanmedian(sep.k_rel_lo[away])):.0f} %; peak compliance excess in each "
        f"zone: {', '.join(parts) or 'none separable'}."
    ]


def run_one(csv: Path, vehicle_kind: str) -> dict[str, object]:
    res, _, truth, elapsed = process_one(csv, vehicle_kind)
    npz = dict(np.load(csv.with_suffix(".truth.npz")))
    return {
        "run": csv.stem,
        "time_s": elapsed,
        "geometry_smooth": bool(res.geometry_check.smooth),
        **zone_scores(res, zones_as_built(truth, npz)),
        "listed": zone_scores(res, truth["zones"])["zones"],
        **profile_scores(res, npz),
    }


def table(results: list[dict[str, object]], vehicle_kind: str) -> list[str]:
    lines = [
        f"Vehicle given: **{vehicle_kind}**.",
        "",
        "Zones where the peer's mesh has them (benchmarks/peer_truth.py); the README's listed "
        "positions alongside.",
        "",
        "| run | zone (as built; listed) | reported | Δstart, Δend (m) | vs listed (m) "
        "| loss true → reported (Δ pp) | found |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in results:
        for z, zl in zip(r["zones"], r["listed"], strict=True):  # type: ignore[call-overload]
            a, b, loss = z["true"]
            la, lb, _ = zl["true"]
            head = f"| {r['run']} | {a:.1f}-{b:.1f} m; {la:.1f}-{lb:.1f} m, {loss:.0f} % |"
            if "reported" in z:
                ra, rb, rl = z["reported"]
                lines.append(
                    f"{head} {ra:.1f}-{rb:.1f} m | {z['d_start']:+.1f}, {z['d_end']:+.1f} | "
                    f"{zl['d_start']:+.1f}, {zl['d_end']:+.1f} | {loss:.0f} → {rl:.0f} % "
                    f"({z['loss_err_pp']:+.1f}) | {'yes' if z['found'] else 'no'} |"
                )
            else:
                lines.append(f"{head} — | — | — | — | no |")
    lines += [
        "",
        "| run | false zones | rail judged smooth | profile 3-25 m: RMS diff / truth RMS, corr, "
        "gain | 3-40 m: RMS diff / truth RMS, corr, gain | time, s |",
        "|---|---|---|---|---|---|",
    ]
    for r in results:
        fz = ", ".join(f"{a:.1f}-{b:.1f}" for a, b in r["false"]) or "none"  # type: ignore[union-attr]
        lines.append(
            f"| {r['run']} | {fz} | {'yes' if r['geometry_smooth'] else 'no'} | "
            f"{r['rms_diff_3-25']:.3f} / {r['rms_truth_3-25']:.3f} mm, {r['corr_3-25']:.3f}, "
            f"{r['gain_3-25']:.2f} | {r['rms_diff_3-40']:.3f} / {r['rms_truth_3-40']:.3f} mm, "
            f"{r['corr_3-40']:.3f}, {r['gain_3-40']:.2f} | {r['time_s']:.2f} |"
        )
    return lines


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, nargs="+", default=[default_dir()],
                    help="folders of runs, one track each")  # fmt: skip
    ap.add_argument("--vehicle", choices=("bogie", "lumped"), default="bogie")
    ap.add_argument("--runs", nargs="*", default=None, help="run names (default: all)")
    ap.add_argument("--separate", action="store_true", help="the rough runs together")
    ap.add_argument("--compliance-every", type=float, default=0.0, metavar="M",
                    help="with --separate: the compliance excess every M m")  # fmt: skip
    ap.add_argument(
        "--no-rings",
        action="store_true",
        help="with --separate: the passes without their end rings (as before them)",
    )
    ap.add_argument("--ring-variants", action="store_true",
                    help="the separation with other end-ring fits (RING_VARIANTS)")  # fmt: skip
    ap.add_argument("--truth-levels", action="store_true",
                    help="with --separate: the truth levels instead of the product's")  # fmt: skip
    args = ap.parse_args()
    # Every run with its truth: the public ``pub_*`` ones or those made with
    # benchmarks/peer_runs/make_rose_runs.py.
    by_dir = [
        sorted(c for c in d.glob("*.csv") if c.with_suffix(".truth.json").exists())
        for d in args.data
    ]
    if args.runs:
        by_dir = [[c for c in csvs if c.stem in args.runs] for csvs in by_dir]
    if args.ring_variants:
        print("\n".join(ring_variant_lines(by_dir, args.vehicle)))
        return
    if args.separate:
        tally = [0, 0, 0]
        for csvs in by_dir:
            rough = [c for c in csvs if c.stem.endswith("_irr")]
            lines = separate_rough(rough, args.vehicle, args.truth_levels, args.compliance_every,
                                   rings=not args.no_rings, tally=tally)  # fmt: skip
            print("\n".join(lines) + "\n")
        if len(by_dir) > 1:
            print(f"Over {len(by_dir)} tracks: {tally[0]} of {tally[1]} zones found, "
                  f"{tally[2]} false zones.")  # fmt: skip
        return
    results = [run_one(c, args.vehicle) for csvs in by_dir for c in csvs]
    print("\n".join(table(results, args.vehicle)))


if __name__ == "__main__":
    main()
