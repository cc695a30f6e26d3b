"""The peer's (ROSE) truth files read the one way the accuracy benchmark and the tests read them.

A truth JSON describes the vehicle by its whole-vehicle datasheet; :func:`bogie_from_truth`
turns it into the :class:`engine.bogie.BogieParams` a user would register. The truth NPZ gives
the level under each bogie; :func:`bogie_mean_truth` is what the loaded profile is scored
against, :func:`butter_band` the band both are compared in (README of ``peer-bogie``,
section 5).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.signal import butter, sosfiltfilt

from engine.bogie import BogieParams


def bogie_from_truth(truth: dict[str, Any]) -> BogieParams:
    """The vehicle as its datasheet gives it (whole vehicle, SI), from the truth JSON."""
    full = truth["vehicle"]["full_vehicle"]
    per_rail = truth["vehicle"]["per_rail_model"]
    return BogieParams(
        body_mass_kg=full["body_mass_kg"],
        body_pitch_inertia_kgm2=full["body_pitch_inertia_kgm2"],
        bogie_mass_kg=full["bogie_frame_mass_kg_each"],
        bogie_pitch_inertia_kgm2=full["bogie_frame_pitch_inertia_kgm2_each"],
        wheelset_mass_kg=full["wheelset_mass_kg_each"],
        bogie_half_spacing_m=0.5 * full["bogie_centre_distance_m"],
        wheelbase_m=full["wheelbase_m"],
        secondary_k_n_per_m=full["secondary_k_N_per_m_per_bogie_per_side"],
        secondary_c_ns_per_m=full["secondary_c_Ns_per_m_per_bogie_per_side"],
        primary_k_n_per_m=full["primary_k_N_per_m_per_axlebox"],
        primary_c_ns_per_m=full["primary_c_Ns_per_m_per_axlebox"],
        contact_k_n_per_m=per_rail["hertz_k_linearised_at_static_load_N_per_m"],
    )


def bogie_mean_truth(npz: dict[str, Any], grid: NDArray[np.float64]) -> NDArray[np.float64]:
    """The bogie-mean truth level on ``grid`` (m), m; NaN where not both bogies passed."""
    f = np.interp(grid, npz["x_front_bogie"], npz["level_front_bogie"], left=np.nan, right=np.nan)
    r = np.interp(grid, npz["x_rear_bogie"], npz["level_rear_bogie"], left=np.nan, right=np.nan)
    return np.asarray(0.5 * (f + r))


def butter_band(y: NDArray[np.float64], step: float, lo: float, hi: float) -> NDArray[np.float64]:
    """Zero-phase 4th-order Butterworth band-pass in wavenumber (wavelengths lo..hi m; grid
    ``step`` m)."""
    nyq = 0.5 / step
    sos = butter(4, [1.0 / hi / nyq, 1.0 / lo / nyq], btype="band", output="sos")
    return np.asarray(sosfiltfilt(sos, y))
