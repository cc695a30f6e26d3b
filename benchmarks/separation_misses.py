"""Why the rough-rail separation misses a zone: each zone not found, by cause (issue 32).

Run: ``python benchmarks/separation_misses.py [--cases b43,s7,...,d5000] [--vehicles "true
vehicles"]``

The cases and vehicle sets of ``accuracy_bogie_separation.py`` (its cached passes), separated
with the default configuration. For every zone that table does not count as found (both ends
within 1.5 m and the loss within 10 pp), one row:

- the separable share of the zone and its distance to the nearer end of the separable stretch
  (m; negative: the zone lies outside it);
- the detection limit there: the smallest loss the passes detect at ``noise_factor`` standard
  deviations (``1 - k_rel_lo`` of the separation with ``max_detectable_loss`` relaxed, no spot
  kept), its range over the zone; ``>0.9`` beyond the scale of losses;
- how deep the zone's dip stands, in standard deviations, for the two detectors: the lowest
  point of the residual scaled by its local standard deviation (the white threshold) and the
  highest output of the filter matched to the compliance's noise (first round, before any
  dip is taken out), over the zone widened by 2 m; both against ``noise_factor`` (4.5);
- the spot reported over it (Δstart/Δend m, Δloss pp), if any;
- the cause: *merged* (one spot over two zones), *extent out* (which end), *loss out*,
  *not separable* (under half the zone separable), *below the detection limit* (the zone's loss
  under the limit there) or *not detected* (the loss over the limit, the dip under the
  threshold).

``--edge-factors 0.3,0.15``: instead, whether the estimator's standard deviation near the ends
is the measured one. Per ``edge_factor`` (``SeparationConfig``, the error of a pass's level
near its ends; 0.3 the default) and bin of distance to the nearer end of the stretch where the
compliance is defined (``max_detectable_loss`` relaxed), away from the zones (±10 m): the
robust spread of the compliance residual, the median of the estimator's standard deviation,
the robust spread of their ratio (the same ratio near the ends as in the middle: the edge
term is the measured noise), and that of the residual's 3-12 m part (a zone's own
wavelengths) over the standard deviation.

The profile the soft-spot extraction works on is read by wrapping
``engine.separation._soft_spots`` (a diagnostic: the separation itself is unchanged).
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numpy as np  # noqa: E402
from numpy.typing import NDArray  # noqa: E402

import engine.separation as separation  # noqa: E402
from benchmarks.accuracy_bogie_separation import (  # noqa: E402
    CASES,
    calibrated_passes,
    drawn,
    within,
)
from engine.chainage import bandpass_distance  # noqa: E402
from engine.detect import robust_baseline, robust_sigma  # noqa: E402
from engine.intervals import true_runs  # noqa: E402
from engine.matched_dips import _filtered, _run_filters, noise_spectrum  # noqa: E402
from engine.passes import Pass  # noqa: E402
from engine.separation import SeparationConfig, SeparationResult, separate  # noqa: E402
from engine.track import SoftZone  # noqa: E402

DEFAULT_CASES = ("b43,s7,s11,s19,s23,n101,n202,n303,"
                 "d5000,d5001,d5002,d5003,d5004,d5005,d5006")  # fmt: skip


def extraction_inputs(passes: list[Pass], cfg: SeparationConfig) -> tuple[SeparationResult, dict]:
    """The separation of ``passes`` and the arguments its soft-spot extraction was called
    with (grid, dip_mm, dip_sd, trk, cfg, wheels)."""
    seen: dict[str, Any] = {}
    inner = separation._soft_spots

    def spy(*args: Any, **kwargs: Any) -> Any:
        names = ("grid", "dip_mm", "dip_sd", "trk", "cfg", "wheels")
        seen.update(zip(names, args, strict=False))
        seen.update(kwargs)
        return inner(*args, **kwargs)

    separation._soft_spots = spy  # type: ignore[assignment]
    try:
        result = separate(passes, config=cfg)
    finally:
        separation._soft_spots = inner  # type: ignore[assignment]
    return result, seen


def white_and_matched_sigma(seen: dict) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Per point: the residual over its local standard deviation (the white detector's
    statistic, negative down) and the largest matched-filter output over its robust spread
    (positive for a dip), as the extraction forms them."""
    grid, dip_mm, dip_sd, trk, cfg = (seen[k] for k in ("grid", "dip_mm", "dip_sd", "trk", "cfg"))
    wheels = seen.get("wheels", ((((0.0,), (0.0,)), 1.0),))
    step = float(grid[1] - grid[0])
    resid = dip_mm - robust_baseline(dip_mm, step, 40.0)
    sd_eff = np.maximum(np.where(np.isfinite(dip_sd), dip_sd, np.inf), robust_sigma(resid))
    scaled = resid / sd_eff
    matched = np.full(grid.size, np.nan)
    shapes = separation._zone_shapes(step, trk, wheels, cfg)
    spec = noise_spectrum(scaled, step, cfg.lambda_max_m)
    if spec is None:
        return scaled, matched
    runs = [(a, b) for a, b in true_runs(np.isfinite(scaled)) if b - a >= 8]
    longest = max(t.size for _, t in shapes)
    filters = [_run_filters(b - a, longest, step, *spec, shapes) for a, b in runs]
    stats, _ = _filtered(scaled, runs, filters, len(shapes))
    scale = np.array([robust_sigma(row) for row in stats])
    with np.errstate(invalid="ignore", divide="ignore"):
        z = stats / np.where(scale > 0, scale, np.inf)[:, None]
    ok = np.isfinite(z).any(axis=0)
    matched[ok] = np.nanmax(z[:, ok], axis=0)
    return scaled, matched


END_ZONE_M = 30.0
"""A zone this close to an end of the separable stretch (m), or outside it, counts as at the
end in the summary."""


def zone_rows(
    name: str, label: str, passes: list[Pass], zones: tuple[SoftZone, ...], tally: dict
) -> list[str]:
    """One table row per zone of the case not found with this vehicle set; ``tally`` counts
    (at the end or not) -> [zones, found] and cause -> misses."""
    cfg = SeparationConfig()
    sep, seen = extraction_inputs(passes, cfg)
    limits = separate(passes, config=dataclasses.replace(cfg, max_detectable_loss=0.99,
                                                         min_loss=0.99))  # fmt: skip
    scaled, matched = white_and_matched_sigma(seen)
    grid = sep.chainage_m
    runs = [(float(grid[a]), float(grid[b - 1])) for a, b in true_runs(sep.separable)]
    rows = []
    for z in zones:
        inside = (grid >= z.start_m) & (grid <= z.end_m)
        widened = (grid >= z.start_m - 2.0) & (grid <= z.end_m + 2.0)
        hits = [s for s in sep.soft_spots if s.start_m <= z.end_m and s.end_m >= z.start_m]
        # signed distance to the nearer end of the separable stretch: inside it positive
        dist = max((min(z.start_m - a, b - z.end_m) for a, b in runs), default=float("-inf"))
        counts = tally.setdefault(("at an end" if dist <= END_ZONE_M else "inside"), [0, 0])
        counts[0] += 1
        d0 = d1 = dl = float("nan")
        if hits:
            s = hits[0]
            d0, d1, dl = s.start_m - z.start_m, s.end_m - z.end_m, s.loss_pct - 100 * z.loss
            if within(d0, d1, dl):
                counts[1] += 1
                continue
        share = float(sep.separable[inside].mean())
        lim = 1.0 - limits.k_rel_lo[inside]
        lim = lim[np.isfinite(lim)]
        lim_txt = "—" if lim.size == 0 else " – ".join(
            ">0.9" if v > 0.9 else f"{v:.2f}" for v in (lim.min(), lim.max())
        )  # fmt: skip
        white = np.where(widened, scaled, np.nan)
        mf = np.where(widened, matched, np.nan)
        w_txt = f"{-np.nanmin(white):.1f}" if np.isfinite(white).any() else "—"
        m_txt = f"{np.nanmax(mf):.1f}" if np.isfinite(mf).any() else "—"
        if hits:
            s = hits[0]
            others = [
                o for o in zones if o is not z and s.start_m <= o.end_m and s.end_m >= o.start_m
            ]
            if others:
                cause = "merged with a neighbour"
            elif not within(d0, d1, 0.0):
                cause = "extent out (" + ", ".join(
                    e for e, d in (("start", d0), ("end", d1)) if not within(d, 0.0, 0.0)
                ) + ")"  # fmt: skip
            else:
                cause = "loss out"
            reported = f"{d0:+.1f}/{d1:+.1f}, {dl:+.0f}"
        else:
            reported = "missed"
            if share < 0.5:
                cause = "not separable"
            elif lim.size and z.loss < lim.max():
                cause = "below the detection limit"
            else:
                cause = "not detected"
        tally[cause] = tally.get(cause, 0) + 1
        rows.append(
            f"| {name} | {label} | {z.start_m:.1f}-{z.end_m:.1f} m, {100 * z.loss:.0f} % | "
            f"{100 * share:.0f} % | {dist:+.0f} | {lim_txt} | {w_txt} | {m_txt} | {reported} | "
            f"{cause} |"
        )
    return rows


EDGE_BINS_M = (0.0, 10.0, 20.0, 30.0, 45.0, 60.0, np.inf)
SHORT_BAND_M = (3.0, 12.0, 0.3)
"""Band (m, m, taper) of a zone's own wavelengths in the edge check."""


def edge_spread(cases: list[str], label: str, edge_factors: list[float]) -> None:
    """Print, per edge factor and distance bin, the compliance residual's measured spread
    against the estimator's (module docstring)."""
    print("| edge_factor | distance to the end (m) | points | residual spread (µm) "
          "| estimator's sd, median (µm) | spread of residual / sd "
          "| of its 3-12 m part / sd |")  # fmt: skip
    print("|---|---|---|---|---|---|---|")
    for factor in edge_factors:
        cfg = SeparationConfig(max_detectable_loss=0.99, edge_factor=factor)
        bins: list[tuple[list[NDArray[np.float64]], ...]] = [([], [], []) for _ in EDGE_BINS_M[1:]]
        for name in cases:
            case = CASES[name] if name in CASES else drawn(name)
            _, seen = extraction_inputs(calibrated_passes(name, case)[0][label], cfg)
            grid, dip_mm, dip_sd = seen["grid"], seen["dip_mm"], seen["dip_sd"]
            resid = dip_mm - robust_baseline(dip_mm, float(grid[1] - grid[0]), 40.0)
            clear = np.ones(grid.size, dtype=bool)
            for z in case.zones:
                clear &= (grid < z.start_m - 10.0) | (grid > z.end_m + 10.0)
            for a, b in true_runs(np.isfinite(dip_mm)):
                x = grid[a:b]
                dist = np.minimum(x - x[0], x[-1] - x)
                short = bandpass_distance(resid[a:b], float(grid[1] - grid[0]), *SHORT_BAND_M)
                for i, (lo, hi) in enumerate(zip(EDGE_BINS_M[:-1], EDGE_BINS_M[1:], strict=True)):
                    m = (dist >= lo) & (dist < hi) & clear[a:b]
                    bins[i][0].append(resid[a:b][m])
                    bins[i][1].append(dip_sd[a:b][m])
                    bins[i][2].append(short[m])
        for (lo, hi), (rs, sds, shorts) in zip(zip(EDGE_BINS_M[:-1], EDGE_BINS_M[1:], strict=True),
                                       bins, strict=True):  # fmt: skip
            r, sd, sh = np.concatenate(rs), np.concatenate(sds), np.concatenate(shorts)
            if r.size == 0:
                continue
            where = f"{lo:.0f}-{hi:.0f}" if np.isfinite(hi) else f"{lo:.0f}+"
            print(f"| {factor} | {where} | {r.size} | {1e3 * robust_sigma(r):.0f} | "
                  f"{1e3 * float(np.median(sd)):.0f} | {robust_sigma(r / sd):.2f} | "
                  f"{robust_sigma(sh / sd):.2f} |")  # fmt: skip


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", default=DEFAULT_CASES)
    ap.add_argument("--vehicles", default="true vehicles",
                    help="vehicle sets, ';'-separated (the accuracy table's labels)")  # fmt: skip
    ap.add_argument("--edge-factors", default="",
                    help="comma-separated edge factors: the edge-term check instead")  # fmt: skip
    args = ap.parse_args()
    if args.edge_factors:
        edge_spread(args.cases.split(","), args.vehicles.split(";")[0],
                    [float(v) for v in args.edge_factors.split(",")])  # fmt: skip
        return
    print("| case | vehicles | zone | separable | to the separable end (m) | detection limit "
          "| white (σ) | matched (σ) | reported (Δstart/Δend m, Δloss pp) | cause |")  # fmt: skip
    print("|---|---|---|---|---|---|---|---|---|---|")
    tally: dict = {}
    for name in args.cases.split(","):
        case = CASES[name] if name in CASES else drawn(name)
        by_label, _ = calibrated_passes(name, case)
        for label in args.vehicles.split(";"):
            for row in zone_rows(name, label, by_label[label], case.zones, tally):
                print(row, flush=True)
    print()
    for where in ("at an end", "inside"):
        n, found = tally.pop(where, [0, 0])
        print(f"zones {where} (within {END_ZONE_M:.0f} m of an end of the separable stretch, "
              f"or outside it, is at an end): {found}/{n} found")  # fmt: skip
    print("misses by cause: " + ", ".join(f"{k} {v}" for k, v in sorted(tally.items())))


if __name__ == "__main__":
    main()
