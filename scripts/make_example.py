"""Make the example run log shipped in ``examples/`` (and its truth), reproducibly.

    .venv/bin/python scripts/make_example.py        # writes examples/example_run.csv.gz
                                                     # and examples/example_run.truth.json

A 500 m pass at 22 m/s of the paper's Table 1 coach over a straight rail on supports with 5 %
stiffness scatter and two soft zones, written the way an IMU logger writes it: epoch-second
timestamps (20 November 2025, 08:00 UTC), vertical acceleration in g with gravity, pitch rate
in deg/s, speed in km/h, with the sensor noise and bias of the accuracy requirements
(engine.synthetic.REALISTIC_SENSOR). The truth file gives the soft zones, the start chainage
and the recording time: what a user types into the upload form, and what the result should
show.
"""

from __future__ import annotations

import gzip
import io
import json
from datetime import UTC, datetime
from pathlib import Path

import numpy as np

from engine.synthetic import REALISTIC_SENSOR, make_run
from engine.track import SoftZone
from engine.vehicle import GRAVITY

OUT = Path(__file__).resolve().parents[1] / "examples"
RECORDED_AT = datetime(2025, 11, 20, 8, 0, tzinfo=UTC)
ZONES = (SoftZone(140.0, 146.0, 0.5), SoftZone(333.0, 337.0, 0.35))
START_M = 24.13


def main() -> None:
    run = make_run(
        length=500.0, zones=ZONES, speed=22.0, start_chainage_m=START_M, jitter=0.05,
        sensor=REALISTIC_SENSOR, seed=7,
    )  # fmt: skip
    log = run.log
    assert log.speed_mps is not None
    epoch0 = RECORDED_AT.timestamp()
    cols = np.column_stack([
        epoch0 + log.time_s,
        (log.accel_z_mps2 + GRAVITY) / GRAVITY,
        np.degrees(log.pitch_rate_radps),
        log.speed_mps * 3.6,
    ])  # fmt: skip
    text = io.StringIO()
    text.write("timestamp,az_g,gyro_y_dps,speed_kmh\n")
    np.savetxt(text, cols, fmt=["%.3f", "%.8g", "%.8g", "%.6g"], delimiter=",")
    OUT.mkdir(exist_ok=True)
    # mtime=0: the same bytes every time the command runs.
    (OUT / "example_run.csv.gz").write_bytes(
        gzip.compress(text.getvalue().encode(), compresslevel=9, mtime=0)
    )
    truth = {
        "description": "500 m at 22 m/s, Table 1 coach, straight rail, 5 % support scatter, "
        "realistic IMU noise and bias; made by scripts/make_example.py",
        "start_chainage_m": START_M,
        "direction": "increasing",
        "vehicle": "table1",
        "recorded_at": RECORDED_AT.isoformat(),
        "speed_mps": 22.0,
        "n_samples": int(log.n),
        "zones": [
            {"start_m": z.start_m, "end_m": z.end_m, "stiffness_loss_pct": 100 * z.loss}
            for z in ZONES
        ],
        "columns": {
            "timestamp": "epoch seconds",
            "az_g": "vertical acceleration, g, gravity included",
            "gyro_y_dps": "pitch rate, deg/s, nose-up positive",
            "speed_kmh": "speed, km/h",
        },  # fmt: skip
    }
    (OUT / "example_run.truth.json").write_text(json.dumps(truth, indent=2) + "\n")


if __name__ == "__main__":
    main()
