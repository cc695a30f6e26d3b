"""Where the peer's zones are: fits of its truth levels and of an exact static rail.

Run: ``python benchmarks/peer_bogie_zone_geometry.py [--data DIR]`` (default
``$SHARED_DIR/data/peer-bogie``, ``/work/shared`` without it).

On ``pub_coach_smooth``, :func:`engine.stiffness.fit_zone` (the coach's two wheels, band
3-40 m, 40 m running-median baseline) fitted to: the truth's level under the first and the
second wheelset (each wheel's own and its bogie neighbour's load), the truth's front-bogie
mean level, and the bogie-mean level of an exact static Euler-Bernoulli rail (0.3 m
elements) on the truth's sleeper table, with the sleepers at their listed positions and as
ROSE's ``combine_horizontal_tracks`` builds the track (``benchmarks/peer_truth.py``). Prints the
first/last fitted support minus the listed first/last soft sleeper (m) and the loss; then,
per wheel and zone, the RMS residual of the static rail's displacement against the truth's
(gain and offset fitted) for both sleeper positions.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numpy as np  # noqa: E402
import scipy.sparse as sp  # noqa: E402
import scipy.sparse.linalg as spl  # noqa: E402
from numpy.typing import NDArray  # noqa: E402

from benchmarks.peer_truth import joint_gap_m  # noqa: E402
from engine.beam import element_matrices, hermite_shape  # noqa: E402
from engine.chainage import bandpass_distance  # noqa: E402
from engine.detect import robust_baseline  # noqa: E402
from engine.stiffness import fit_zone  # noqa: E402
from engine.track import TrackParams  # noqa: E402

STEP = 0.25
ELEMENT_M = 0.3


class StaticRail:
    """Exact static rail in ``ELEMENT_M`` elements on the given discrete supports."""

    def __init__(self, ei: float, sup_x: NDArray[np.float64], sup_k: NDArray[np.float64]) -> None:
        h = ELEMENT_M
        self.n = int(round(sup_x.max() / h)) + 3
        ke, _ = element_matrices(ei, 1.0, h)
        e = np.arange(self.n - 1)
        idx = 2 * e[:, None] + np.arange(4)[None, :]
        rows = np.repeat(idx, 4, axis=1).ravel()
        cols = np.tile(idx, (1, 4)).ravel()
        vals = np.tile(ke.ravel(), e.size)
        node = 2 * np.rint(sup_x / h).astype(int)
        k = sp.coo_matrix((vals, (rows, cols)), shape=(2 * self.n,) * 2)
        k = k + sp.coo_matrix((sup_k, (node, node)), shape=(2 * self.n,) * 2)
        self.lu = spl.splu(k.tocsc())

    def _loads(self, x: NDArray[np.float64]) -> sp.csc_matrix:
        h = ELEMENT_M
        e = np.clip(np.floor(x / h).astype(int), 0, self.n - 2)
        shape = hermite_shape(x / h - e, h)
        rows = (2 * e[:, None] + np.arange(4)[None, :]).ravel()
        cols = np.repeat(np.arange(x.size), 4)
        return sp.csc_matrix((shape.ravel(), (rows, cols)), shape=(2 * self.n, x.size))

    def level(self, x: NDArray[np.float64], offsets: tuple[float, ...], load: float):
        """Rail level under a wheel at ``x`` with wheels of ``load`` N at ``x + offsets``, m."""
        at = self._loads(x)
        out = np.zeros(x.size)
        for o in offsets:
            w = self.lu.solve(self._loads(x + o).toarray())
            out -= load * np.asarray(at.multiply(w).sum(axis=0)).ravel()
        return out


def residual_mm(grid: NDArray[np.float64], x, y) -> NDArray[np.float64]:
    lv = bandpass_distance(np.interp(grid, x, y * 1e3, left=np.nan, right=np.nan), STEP, 3, 40)
    return lv - robust_baseline(lv, STEP, 40.0)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    default = Path(os.environ.get("SHARED_DIR", "/work/shared")) / "data" / "peer-bogie"
    ap.add_argument("--data", type=Path, default=default)
    run = ap.parse_args().data / "pub_coach_smooth"
    truth = json.loads(run.with_suffix(".truth.json").read_text())
    npz = dict(np.load(run.with_suffix(".truth.npz")))
    a = 0.5 * truth["vehicle"]["full_vehicle"]["wheelbase_m"]
    load = float(truth["vehicle"]["per_rail_model"]["static_wheel_load_N"])
    zones = truth["zones"]
    segment = np.concatenate([[0], np.cumsum(np.diff(npz["sleeper_loss"]) != 0)])
    rails = {
        f"static rail, {name}": StaticRail(
            truth["track"]["EI"], npz["sleeper_x"] + gap * segment, npz["sleeper_k"]
        )
        for name, gap in (("listed sleepers", 0.0), ("sleepers as ROSE builds", joint_gap_m(truth)))
    }
    grid = np.arange(60.0, 360.0, STEP)
    pair = ((0.0, -2 * a), (0.0, 2 * a))  # each wheelset's own load, then its neighbour's
    cases: dict[str, tuple[NDArray[np.float64], dict]] = {}
    for w in (0, 1):
        o = pair[w][1]
        sets = (((0.0, o), load), ((0.0,), load / 2), ((o,), -load / 2))
        cases[f"truth, wheelset {w + 1}"] = (
            residual_mm(grid, npz["x_wheels"][w], npz["level_wheels"][w]),
            {"wheel_sets": sets},
        )
    both = {"wheel_offsets_m": (a, -a)}
    cases["truth, front bogie mean"] = (
        residual_mm(grid, npz["x_front_bogie"], npz["level_front_bogie"]),
        both,
    )
    for name, rail in rails.items():
        mean = 0.5 * (
            rail.level(grid + a, (0.0, -2 * a), load) + rail.level(grid - a, (0.0, 2 * a), load)
        )
        cases[name] = (residual_mm(grid, grid, mean), both)
    trk = TrackParams()  # what the product fits with: UIC60 on 80 MN/m, the peer's nominal
    print(
        "| fit on | "
        + " | ".join(
            f"{z['start_m']}-{z['end_m']} m, {100 * z['stiffness_loss']:.0f} %" for z in zones
        )
        + " |"
    )
    print("|---|" + "---|" * len(zones))
    for name, (r, kw) in cases.items():
        cells = []
        for z in zones:
            f = fit_zone(grid, r, z["start_m"], z["end_m"], trk, load, 3.0, 40.0, **kw)
            cells.append(
                f"{f.start_m - z['start_m']:+.1f}/{f.end_m - z['end_m']:+.1f}, {100 * f.loss:.0f} %"
            )
        print(f"| {name} | " + " | ".join(cells) + " |")
    print("\nStatic rail vs the truth's rail displacement under a wheel (RMS residual, µm):")
    for w in (0, 1):
        x, u = npz["x_wheels"][w], npz["rail_disp_wheels"][w]
        for z in zones:
            m = (x > z["start_m"] - 12) & (x < z["end_m"] + 14)
            xs, us = x[m][::5], u[m][::5]
            cells = []
            for name, rail in rails.items():
                mod = rail.level(xs, pair[w], load)
                A = np.vstack([mod, np.ones_like(mod)]).T
                coef, *_ = np.linalg.lstsq(A, us, rcond=None)
                res = us - A @ coef
                cells.append(f"{name}: {1e6 * np.sqrt(np.mean(res**2)):.1f} (gain {coef[0]:.3f})")
            print(f"  wheelset {w + 1}, zone {z['start_m']} m: " + "; ".join(cells))


if __name__ == "__main__":
    main()
