"""One pass at a time over the public MEMS look-alike runs: the default method against wiener.

Run: ``SHARED_DIR=/path/to/shared python benchmarks/accuracy_public_mems.py`` (about 10 s;
default ``../shared`` next to the repository). For each ``mems/sample_noisy_<grade>_NN.csv``
(six industrial and six consumer passes of the public two-zone track) the pass is processed
from its true start chainage (its ``.truth.json``) with each method; printed: zones found
(a reported spot overlapping a true zone), false zones, the pass's own 3 m detection limit and
the robust spread of its residual profile. A check on data the methods were not tuned on.
"""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from engine.logio import read_run_csv  # noqa: E402
from engine.pipeline import ProcessConfig, process_run  # noqa: E402
from engine.setup import RunSetup, prepare_run

METHODS = ("spectral", "wiener")


def main() -> None:
    root = Path(os.environ.get("SHARED_DIR", Path(__file__).resolve().parents[2] / "shared"))
    files = sorted((root / "data" / "mems").glob("sample_noisy_*_[0-9][0-9].csv"))
    if not files:
        sys.exit(f"no mems/sample_noisy_*.csv under {root / 'data'} (set SHARED_DIR)")
    print("| pass | " + " | ".join(f"{m}: zones, false, limit 3 m, σ mm" for m in METHODS) + " |")
    print("|---|" + "---|" * len(METHODS))
    totals = {m: [0, 0, 0] for m in METHODS}
    for f in files:
        truth = json.loads(f.with_suffix(".truth.json").read_text())
        log = read_run_csv(f)
        cells = []
        for m in METHODS:
            res = process_run(
                prepare_run(
                    log,
                    RunSetup(
                        start_chainage_m=truth["start_chainage_m"], config=ProcessConfig(method=m)
                    ),
                )
            )
            zones = truth["zones"]
            hit = [any(s.end_m >= z["start_m"] and s.start_m <= z["end_m"]
                       for s in res.soft_spots) for z in zones]  # fmt: skip
            false = sum(not any(s.end_m >= z["start_m"] and s.start_m <= z["end_m"]
                                for z in zones) for s in res.soft_spots)  # fmt: skip
            assert res.detection_limit is not None
            lim = res.detection_limit.min_loss_pct[0]
            cells.append(f"{sum(hit)}/{len(zones)}, {false}, {lim:.0f} %, "
                         f"{res.extras['residual_sigma_mm']:.3f}")  # fmt: skip
            t = totals[m]
            t[0], t[1], t[2] = t[0] + sum(hit), t[1] + len(zones), t[2] + false
        print(f"| {f.stem} | " + " | ".join(cells) + " |", flush=True)
    print(
        "\nTotals: "
        + "; ".join(f"{m} {t[0]}/{t[1]} zones, {t[2]} false" for m, t in totals.items())
    )


if __name__ == "__main__":
    main()
