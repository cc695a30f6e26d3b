"""The peer's (ROSE) truth files read the one way the accuracy benchmark and the tests read them.

A truth JSON describes the vehicle by its whole-vehicle datasheet; :func:`bogie_from_truth`
turns it into the :class:`engine.bogie.BogieParams` a user would register. The truth NPZ gives
the level under each bogie; :func:`bogie_mean_truth` is what the loaded profile is scored
against, :func:`butter_band` the band both are compared in (README of ``peer-bogie``,
section 5).

Where the zones are. The README lists each zone by the index position of its sleepers
(``i * spacing``). The track was assembled from one ROSE track segment per zone and per
stretch between zones with ROSE's ``combine_horizontal_tracks``
(``rose/pre_process/mesh_utils.py`` at the README's commit): each segment's rail ends at its
last rail node, ``spacing / n_rail_per_sleeper`` short of one more bay past its last sleeper,
and the next segment starts one sleeper distance past that node. With two rail elements per
bay every joint therefore adds half a bay (0.3 m): the bay across a joint is 0.9 m, and the
k-th segment's sleepers sit ``k * 0.3`` m further along than listed. The wheels run on that
mesh, so every chainage of the run (``x_wheels``, the irregularity, the CSV's start) is in its
coordinate, and the zones' sleepers are ``0.3, 0.9, 1.5`` m past the listed ones.
``tests/engine/test_peer_bogie.py`` checks this on the truth itself (the sleeper ripple of the
rail under a wheel is half a bay out of phase inside every zone).

Runs made as one uniform mesh (``benchmarks/peer_runs/make_rose_runs.py``: each zone's
ballast springs a model part of their own, no joints) say so with ``track.segment_joints``
false; their sleepers are where listed and nothing is moved. A truth without the key is one
of the public runs, built from segments.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.signal import butter, sosfiltfilt

from engine.bogie import BogieParams

FOUND_TOL_M = 1.5
"""A found zone's ends lie within this of the true ones, m (README of ``peer-bogie``, §5)."""
FOUND_TOL_PP = 10.0
"""A zone's loss error passes within this, percentage points (the same section)."""


def ends_within(d_start_m: float, d_end_m: float, tol_m: float = FOUND_TOL_M) -> bool:
    """Whether both end errors (m) are within ``tol_m``, compared to the millimetre: a reported
    end lies half a support spacing off the supports, so on zones whose ends are on that grid
    an end error is often exactly 1.5 m, and the last bit of a float sum must not decide it."""
    return round(abs(d_start_m), 3) <= tol_m and round(abs(d_end_m), 3) <= tol_m


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


def joint_gap_m(truth: dict) -> float:
    """Extra length ROSE's ``combine_horizontal_tracks`` puts at each segment joint, m."""
    trk = truth["track"]
    return float(trk["spacing"]) * (1.0 - 1.0 / int(trk["n_rail_per_sleeper"]))


def has_segment_joints(truth: dict) -> bool:
    """Whether the peer's track was joined from segments (the public runs) or is one mesh."""
    return bool(truth["track"].get("segment_joints", True))


def zones_as_built(truth: dict, npz: dict) -> list[dict]:
    """The truth's zones moved to where the peer's mesh has their sleepers.

    Each zone is a segment of its own, so a segment starts wherever the sleepers' loss
    changes; a sleeper in segment ``k`` (0 = the first) lies ``k * joint_gap_m`` past its
    listed position. On a track without joints (:func:`has_segment_joints`) nothing moves.
    Returns copies of ``truth["zones"]`` with ``start_m``/``end_m`` moved and the listed ones
    kept as ``listed_start_m``/``listed_end_m``.
    """
    sx = np.asarray(npz["sleeper_x"], dtype=float)
    segment = np.concatenate([[0], np.cumsum(np.diff(npz["sleeper_loss"]) != 0)])
    gap = joint_gap_m(truth) if has_segment_joints(truth) else 0.0
    out = []
    for z in truth["zones"]:
        k = int(segment[int(np.argmin(np.abs(sx - z["start_m"])))])
        out.append(
            z
            | {
                "start_m": z["start_m"] + k * gap,
                "end_m": z["end_m"] + k * gap,
                "listed_start_m": z["start_m"],
                "listed_end_m": z["end_m"],
            }
        )
    return out
