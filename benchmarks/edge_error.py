"""Where a pass's level error near its ends comes from, on rough rail (issue 32).

Run: ``python benchmarks/edge_error.py [--seeds 9101-9104] [--peer]``

Per seed a 700 m German low-disturbance track (5 % support scatter, no zone) is passed by the
bogie coach at 28 m/s and the freight wagon at 18 m/s (true vehicles, MEMS sensor at 500 Hz,
true start). Each log is processed whole and cut: the cut log starts and ends 150 m inside
the whole one, so its ends lie where the whole log's level has no end error, with the same
sensor noise and a vehicle already moving (its state at the cut's first sample unknown).
On the cut log's covered stretch, by distance ``d`` to its nearer end, the RMS of

- ``total``: the cut log's level band-passed on its own coverage (as the separation does,
  ``bandpass_distance`` 3-40 m) minus the truth band-passed twice on the whole coverage (the
  level carries the inversion's band window, the same raised-cosine band in time at a
  constant speed, before the band-pass);
- ``inversion``: the cut log's level minus the whole log's, both band-passed on the cut's
  coverage (the inversion's end error alone: taper, wrap-around, unknown initial state);
  ``inversion, raw level`` the same unfiltered (what the separation's fit is given);
- ``band-pass``: the whole log's level band-passed on the cut's coverage minus band-passed on
  its own (the band filter's end error on an end-free level);
- ``baseline``: the 40 m running baseline of the whole log's level taken on the cut's
  coverage minus on its own (what the detector's residual gets from the ends);
- ``floor``: the whole log's band-passed level minus that truth (the error away from any
  end); ``floor, truth band-passed once``: against the truth band-passed once (what the
  band's tapers alone make of a comparison that ignores the inversion's window);

so that ``total = inversion + band-pass + floor`` point by point; and the truth's band-passed
RMS. ``--peer`` adds the public peer runs' ``total`` against their
bogie-mean truth band-passed twice on the same stretch (no cut: their ends are the logs'
own, and the truth's own band-pass shares the band filter's end error there).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numpy as np  # noqa: E402
from numpy.typing import NDArray  # noqa: E402

from benchmarks.peer_truth import bogie_mean_truth  # noqa: E402
from engine.bogie import FREIGHT_WAGON, PASSENGER_COACH  # noqa: E402
from engine.chainage import PRODUCT_BAND_M, bandpass_distance  # noqa: E402
from engine.detect import robust_baseline, robust_sigma  # noqa: E402
from engine.logio import read_run_csv  # noqa: E402
from engine.pipeline import process_run  # noqa: E402
from engine.results import ProcessResult  # noqa: E402
from engine.separation import SeparationConfig  # noqa: E402
from engine.setup import RunSetup, prepare_run  # noqa: E402
from engine.synthetic import REALISTIC_SENSOR, make_run, make_track  # noqa: E402
from engine.vehicle_kinds import Vehicle  # noqa: E402

BINS_M = (0.0, 25.0, 50.0, 75.0, 100.0, 125.0, 150.0, 175.0, 250.0)
CUT_M = 150.0
LO, HI = PRODUCT_BAND_M
TAPER = 0.3
BASELINE_M = 40.0


def bp(y: NDArray[np.float64], step: float) -> NDArray[np.float64]:
    """The separation's band-pass on the finite stretch of ``y``."""
    return bandpass_distance(y, step, LO, HI, TAPER)


def cut_log(log, t0: float, t1: float):  # type: ignore[no-untyped-def]
    """The samples of ``log`` in [t0, t1) s, time from zero."""
    keep = (log.time_s >= t0) & (log.time_s < t1)
    fields = {
        f.name: (getattr(log, f.name)[keep] if getattr(log, f.name) is not None else None)
        for f in dataclasses.fields(log)
    }
    fields["time_s"] = fields["time_s"] - fields["time_s"][0]
    return type(log)(**fields)


def process(log, start: float, vehicle: Vehicle) -> ProcessResult:  # type: ignore[no-untyped-def]
    return process_run(prepare_run(log, RunSetup(start, vehicle=vehicle)))


def by_distance(d: NDArray[np.float64], err: NDArray[np.float64]) -> list[float]:
    """RMS of ``err`` per bin of ``d`` (:data:`BINS_M`), mm."""
    out = []
    for a, b in zip(BINS_M[:-1], BINS_M[1:], strict=True):
        sel = (d >= a) & (d < b) & np.isfinite(err)
        out.append(float(np.sqrt(np.mean(err[sel] ** 2))) if sel.any() else float("nan"))
    return out


def distance_to_ends(ok: NDArray[np.bool_], step: float) -> NDArray[np.float64]:
    idx = np.flatnonzero(ok)
    i = np.arange(ok.size)
    return np.where(ok, np.minimum(i - idx[0], idx[-1] - i) * step, np.nan)


def own_run(seed: int, kind: str) -> dict[str, list[float]]:
    vehicle = PASSENGER_COACH if kind == "coach" else FREIGHT_WAGON
    speed = 28.0 if kind == "coach" else 18.0
    sensor = dataclasses.replace(REALISTIC_SENSOR, sample_rate_hz=500.0)
    track = make_track(700.0, jitter=0.05, irregularity="german-low", seed=seed)
    run = make_run(track=track, vehicle=vehicle, speed=speed, sensor=sensor, sim_rate_hz=500.0,
                   seed=seed + 1000, start_chainage_m=12.0)  # fmt: skip
    whole = process(run.log, run.start_chainage_m, vehicle)
    t0, t1 = CUT_M / speed, run.log.time_s[-1] - CUT_M / speed
    part = process(cut_log(run.log, t0, t1), run.start_chainage_m + speed * t0, vehicle)
    step = float(whole.chainage_m[1] - whole.chainage_m[0])
    grid = whole.chainage_m
    # the cut's level on the whole log's grid
    lvl = np.interp(grid, part.chainage_m, part.level_mm, left=np.nan, right=np.nan)
    ok = np.isfinite(lvl) & np.isfinite(whole.level_mm)
    lvl = np.where(ok, lvl, np.nan)
    whole_in = np.where(ok, whole.level_mm, np.nan)
    d = distance_to_ends(ok, step)
    truth_bp = bp(run.true_profile(grid), step)
    whole_bp = bp(whole.level_mm, step)
    # the level carries the inversion's band window already: band-passed, it is windowed twice
    truth_ref = bp(truth_bp, step)
    base_part = robust_baseline(whole_in, step, BASELINE_M)
    base_whole = robust_baseline(whole.level_mm, step, BASELINE_M)
    return {
        "total": by_distance(d, bp(lvl, step) - truth_ref),
        "inversion": by_distance(d, bp(lvl, step) - bp(whole_in, step)),
        "inversion, raw level": by_distance(d, lvl - whole.level_mm),
        "raw / sigma_rail": by_distance(d, (lvl - whole.level_mm) / robust_sigma(lvl[::4])),
        "band-pass": by_distance(d, bp(whole_in, step) - whole_bp),
        "baseline": by_distance(d, base_part - base_whole),
        "floor": by_distance(d, whole_bp - truth_ref),
        "floor, truth band-passed once": by_distance(d, whole_bp - truth_bp),
        "truth": by_distance(d, truth_bp),
    }


def peer_runs(peer_dir: Path) -> dict[str, dict[str, list[float]]]:
    from benchmarks.accuracy_peer_bogie import bogie_from_truth

    out = {}
    for name in ("pub_coach_irr", "pub_freight_irr"):
        csv = peer_dir / f"{name}.csv"
        truth = json.loads(csv.with_suffix(".truth.json").read_text())
        npz = dict(np.load(csv.with_suffix(".truth.npz")))
        res = process(read_run_csv(csv), truth["start_chainage_m"], bogie_from_truth(truth))
        grid = res.chainage_m
        step = float(grid[1] - grid[0])
        t = bogie_mean_truth(npz, grid) * 1e3
        ok = np.isfinite(t) & np.isfinite(res.level_mm)
        d = distance_to_ends(ok, step)
        t_bp = bp(np.where(ok, t, np.nan), step)
        out[name] = {
            "total": by_distance(d, bp(np.where(ok, res.level_mm, np.nan), step)
                                 - bp(t_bp, step)),
            "truth": by_distance(d, t_bp),
        }  # fmt: skip
    return out


def bin_centres() -> NDArray[np.float64]:
    return np.array([0.5 * (a + b) for a, b in zip(BINS_M[:-1], BINS_M[1:], strict=True)])


def edge_law(ratio: list[float]) -> tuple[float, float]:
    """``(factor, decay m)`` of ``factor * exp(-d / decay)`` fitted (log-linear) to the edge
    part of ``raw / sigma_rail`` (less its value beyond 175 m, in quadrature) at 25-150 m."""
    r = np.asarray(ratio)
    mid = bin_centres()
    edge = np.sqrt(np.maximum(r**2 - r[-1] ** 2, 1e-12))
    sel = (mid > 25.0) & (mid < 150.0)
    slope, icpt = np.polyfit(mid[sel], np.log(edge[sel]), 1)
    return float(np.exp(icpt)), float(-1.0 / slope)


def table(rows: dict[str, list[float]]) -> list[str]:
    head = " | ".join(f"{a:g}-{b:g}" for a, b in zip(BINS_M[:-1], BINS_M[1:], strict=True))
    lines = [f"| RMS, mm, by d (m) | {head} |", "|---" * (len(BINS_M)) + "|"]
    for k, v in rows.items():
        lines.append(f"| {k} | " + " | ".join(f"{x:.3f}" for x in v) + " |")
    return lines


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="9101-9104")
    ap.add_argument("--peer", action="store_true")
    ap.add_argument("--peer-dir", default="/work/shared/data/peer-bogie")
    args = ap.parse_args()
    a, _, b = args.seeds.partition("-")
    seeds = range(int(a), int(b or a) + 1)
    for kind in ("coach", "wagon"):
        per = [own_run(s, kind) for s in seeds]
        rows = {k: list(np.sqrt(np.nanmean(np.square([p[k] for p in per]), axis=0)))
                for k in per[0]}  # fmt: skip
        print(f"\n{kind}, seeds {args.seeds} (RMS over the runs)")
        print("\n".join(table(rows)))
        factor, decay = edge_law(rows["raw / sigma_rail"])
        cfg = SeparationConfig()
        decay_now = cfg.edge_decay_m or 1.15 * cfg.lambda_max_m
        law = [cfg.edge_factor * np.exp(-m / decay_now) for m in bin_centres()]
        print("\n".join(table({f"law now ({cfg.edge_factor:g}, {decay_now:.0f} m)": law})[2:]))
        print(f"edge law fitted: factor {factor:.2f}, decay {decay:.0f} m")
    if args.peer:
        for name, rows in peer_runs(Path(args.peer_dir)).items():
            print(f"\n{name}")
            print("\n".join(table(rows)))


if __name__ == "__main__":
    main()
