"""The peer's (ROSE) bogie runs of ``shared/data/peer-bogie``: the vehicle from their truth
JSON's datasheet and the zones where the peer's track mesh actually has them.

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
"""

from __future__ import annotations

import numpy as np

from engine.bogie import BogieParams


def datasheet(truth: dict) -> BogieParams:
    """The vehicle as its datasheet gives it (whole vehicle), from the truth JSON."""
    full = truth["vehicle"]["full_vehicle"]
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
        contact_k_n_per_m=truth["contact"]["k_linearised_N_per_m"],
    )


def joint_gap_m(truth: dict) -> float:
    """Extra length ROSE's ``combine_horizontal_tracks`` puts at each segment joint, m."""
    trk = truth["track"]
    return float(trk["spacing"]) * (1.0 - 1.0 / int(trk["n_rail_per_sleeper"]))


def zones_as_built(truth: dict, npz: dict) -> list[dict]:
    """The truth's zones moved to where the peer's mesh has their sleepers.

    Each zone is a segment of its own, so a segment starts wherever the sleepers' loss
    changes; a sleeper in segment ``k`` (0 = the first) lies ``k * joint_gap_m`` past its
    listed position. Returns copies of ``truth["zones"]`` with ``start_m``/``end_m`` moved
    and the listed ones kept as ``listed_start_m``/``listed_end_m``.
    """
    sx = np.asarray(npz["sleeper_x"], dtype=float)
    segment = np.concatenate([[0], np.cumsum(np.diff(npz["sleeper_loss"]) != 0)])
    gap = joint_gap_m(truth)
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
