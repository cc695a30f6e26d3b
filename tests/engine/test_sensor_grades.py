"""Sensor grades: the generated imperfections have the figures the grade states."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from scipy.signal import welch

from engine.errors import ParameterError
from engine.sensor import (
    SENSOR_GRADES,
    SensorModel,
    apply_sensor,
    gauss_markov,
    sensor_for_grade,
)
from engine.spectral import estimate_white_noise


def _log(sensor: SensorModel, seconds: float = 120.0, rate: float = 1000.0, seed: int = 4):
    t = np.arange(int(seconds * rate)) / rate
    zero = np.zeros_like(t)
    return apply_sensor(t, zero, zero, np.full_like(t, 20.0), sensor, seed=seed)


def test_density_gives_the_per_sample_std_of_sensors_md() -> None:
    """Densities integrate over fs/2: the logged std and the one-sided PSD are the figures."""
    g = SENSOR_GRADES["industrial-mems"]
    for rate in (1000.0, 500.0):
        only_white = SensorModel(
            accel_noise_density=g.accel_noise_density, gyro_noise_density=g.gyro_noise_density
        )
        log = _log(only_white, rate=rate)
        sa, sg = g.white_noise(rate)
        assert np.std(log.accel_z_mps2) == pytest.approx(sa, rel=0.02)
        assert np.std(log.pitch_rate_radps) == pytest.approx(sg, rel=0.02)
        f, p = welch(log.accel_z_mps2, fs=rate, nperseg=1024)
        assert math.sqrt(np.median(p[5:-5])) == pytest.approx(g.accel_noise_density, rel=0.05)
    # sensors.md's table at 1 kHz
    expected = {
        "fibre-optic": (0.005, 1.0e-4),
        "tactical-mems": (0.0055, 5.9e-4),
        "industrial-mems": (0.013, 1.3e-3),
        "consumer-mems": (0.050, 4.3e-3),
    }
    for name, (a, w) in expected.items():
        sa, sg = SENSOR_GRADES[name].white_noise(1000.0)
        assert sa == pytest.approx(a, rel=0.02) and sg == pytest.approx(w, rel=0.02), name


def test_the_inversions_noise_estimate_reads_each_grade() -> None:
    """What the inversion measures on a grade's log is the grade's white noise (±10 %),
    with wander, quantisation and jitter all switched on."""
    for name, g in SENSOR_GRADES.items():
        log = _log(g.sensor(1000.0, seed=2, digits=None), seconds=60.0)
        sa, sg = g.white_noise(1000.0)
        assert estimate_white_noise(log.accel_z_mps2, log.dt) == pytest.approx(sa, rel=0.1), name
        assert estimate_white_noise(log.pitch_rate_radps, log.dt) == pytest.approx(sg, rel=0.1), (
            name
        )


def test_bias_per_pass_is_drawn_within_the_grade_and_seeded() -> None:
    """Each seed draws its own bias within ± the grade's; no seed gives the full bias; the
    logged mean is that bias (the wander averages out over many correlation times)."""
    g = SENSOR_GRADES["consumer-mems"]
    biases = [g.sensor(1000.0, seed=s).accel_bias for s in range(40)]
    assert max(abs(b) for b in biases) <= g.accel_bias_mps2
    assert min(biases) < 0 < max(biases)
    assert g.sensor(1000.0, seed=5) == g.sensor(1000.0, seed=5)
    assert g.sensor(1000.0).accel_bias == g.accel_bias_mps2
    sens = dataclasses.replace(g.sensor(1000.0, seed=7, digits=None), bias_correlation_s=1.0)
    log = _log(sens, seconds=100.0)
    assert np.mean(log.accel_z_mps2) == pytest.approx(sens.accel_bias, abs=2e-3)
    assert np.mean(log.pitch_rate_radps) == pytest.approx(sens.gyro_bias, abs=2e-5)


def test_quantisation_step() -> None:
    """Every logged value is a whole number of LSBs, and a finer LSB is not."""
    g = SENSOR_GRADES["consumer-mems"]
    sens = g.sensor(1000.0, seed=1, digits=None)
    log = _log(sens, seconds=5.0)
    for x, lsb in ((log.accel_z_mps2, sens.accel_lsb), (log.pitch_rate_radps, sens.gyro_lsb)):
        k = x / lsb
        assert np.max(np.abs(k - np.round(k))) < 1e-6
        assert np.any(np.round(k) % 2 == 1)  # the step is one LSB, not a coarser one
        assert np.unique(np.round(k)).size > 20  # the noise spans many steps


def test_bias_wander_has_its_std_and_correlation_time() -> None:
    """The Gauss-Markov wander: stationary std sigma, lag-tau correlation exp(-1)."""
    rng = np.random.default_rng(0)
    b = np.stack([gauss_markov(rng, 4000, 0.1, 2.0, 10.0) for _ in range(200)])
    assert np.std(b) == pytest.approx(2.0, rel=0.05)
    lag = 100  # 10 s
    r = np.mean(b[:, :-lag] * b[:, lag:]) / np.var(b)
    assert r == pytest.approx(math.exp(-1.0), abs=0.05)


def test_jitter_samples_the_signal_off_its_logged_time() -> None:
    """A 10 Hz sine sampled with 50 µs jitter: error RMS = jitter x RMS slope."""
    rate, a, f, jit = 1000.0, 1.0, 10.0, 50e-6
    t = np.arange(60000) / rate
    x = a * np.sin(2 * np.pi * f * t)
    log = apply_sensor(t, x, x, np.full_like(t, 20.0), SensorModel(time_jitter_s=jit), seed=1)
    err = log.accel_z_mps2 - x
    assert np.std(err) == pytest.approx(jit * 2 * np.pi * f * a / math.sqrt(2), rel=0.05)


def test_a_model_without_the_new_imperfections_writes_the_same_log() -> None:
    """Backward compatible: white noise and bias draw exactly as before."""
    t = np.arange(2000) / 1000.0
    x = np.sin(t)
    sens = SensorModel(accel_noise=0.01, gyro_noise=1e-3, accel_bias=0.1, gyro_bias=1e-3)
    log = apply_sensor(t, x, x, np.full_like(t, 20.0), sens, seed=9)
    rng = np.random.default_rng(9)
    na, ng = rng.normal(0.0, 0.01, t.size), rng.normal(0.0, 1e-3, t.size)
    np.testing.assert_array_equal(log.accel_z_mps2, x + 0.1 + 0.0 * t + na)
    np.testing.assert_array_equal(log.pitch_rate_radps, x + 1e-3 + 0.0 * t + ng)


def test_unknown_grade_and_bad_figures_are_named() -> None:
    """An unknown grade names the field and the choices; a negative density its field."""
    with pytest.raises(ParameterError, match="fibre-optic") as e:
        sensor_for_grade("military", 1000.0)
    assert e.value.field == "sensor_grade"
    with pytest.raises(ParameterError) as e2:
        SensorModel(accel_noise_density=-1.0)
    assert e2.value.field == "accel_noise_density"
