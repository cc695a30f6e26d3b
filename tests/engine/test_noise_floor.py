"""The spectral inverse's noise weighting has a floor (issue 16, Medium 10): a noise-free gyro
beside a noisy accelerometer made every bin's normal matrix singular (LinAlgError)."""

from __future__ import annotations

import numpy as np

from engine.pipeline import process_run
from engine.sensor import SensorModel
from engine.setup import RunSetup, prepare_run
from engine.spectral import NOISE_RATIO_RANGE, noise_weights_sigma
from engine.synthetic import make_run
from engine.track import SoftZone


def test_a_clean_gyro_beside_a_noisy_accelerometer_inverts() -> None:
    """The probe's log: exact pitch rate, accelerometer with 0.5 m/s² noise. It inverts (no
    LinAlgError) to a finite profile; with moderate noise the soft zone is still found."""
    for accel_noise in (0.5, 0.01):
        run = make_run(length=200.0, zones=[SoftZone(90.0, 95.0, 0.5)], speed=20.0,
                       start_chainage_m=12.0, sensor=SensorModel(accel_noise=accel_noise),
                       seed=1)  # fmt: skip
        result = process_run(prepare_run(run.log, RunSetup(start_chainage_m=12.0)))
        assert np.isfinite(result.level_mm[np.isfinite(result.level_mm)]).all()
        assert np.isfinite(result.level_mm).mean() > 0.5
    assert any(s.start_m <= 96 and s.end_m >= 89 for s in result.soft_spots)


def test_noise_levels_keep_a_bounded_ratio() -> None:
    typical = 1e-4 / 5e-3
    sa, sg = noise_weights_sigma(0.5, 1e-300)
    assert sa == 0.5 and np.isclose(sg / sa / typical, 1 / NOISE_RATIO_RANGE)
    sa, sg = noise_weights_sigma(0.0, 1e-4)  # an unknown accel noise: the typical one
    assert (sa, sg) == (5e-3, 1e-4)
    sa, sg = noise_weights_sigma(1e-300, 1e-4)
    assert sg == 1e-4 and np.isclose(sg / sa / typical, NOISE_RATIO_RANGE)
    assert noise_weights_sigma(4e-3, 2e-4) == (4e-3, 2e-4)  # ordinary levels untouched
