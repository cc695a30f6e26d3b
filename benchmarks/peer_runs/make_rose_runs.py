"""Unseen peer runs made with ROSE, in exactly the public peer runs' format.

The public peer runs (``$SHARED_DIR/data/peer-bogie``, its README) were made with ROSE, a
train-track code independent of this product. This script makes more runs the same way, with
other vehicles, zones, speeds and rail, so the product can be judged on runs nobody tuned to.
It is a benchmark tool, not part of the product: ROSE is imported here only and must never
become a dependency of ``engine`` or ``app``.

Licence. ROSE (https://github.com/PlatypusBytes/ROSE, commit b92ff30) is BSD-3-Clause,
"Copyright (c) 2025, ROSE"; PuggleSolvers 1.2.0 (its time integration) is MIT. Neither is
copied here; the script only calls their public classes.

Install (a separate venv, never the product's)::

    git -C /work/.mirror/PlatypusBytes+ROSE/repo archive HEAD -- rose rose_libs run_rose \\
        pyproject.toml setup.cfg README.md LICENSE.txt | tar -x -C /work/rose-src
    python3.11 -m venv /work/rose-venv
    /work/rose-venv/bin/pip install numpy scipy PuggleSolvers==1.2.0 matplotlib tqdm

(``tests/test_data`` of the mirror holds large files that are absent, hence the path list.)

Run (one case per process; each took 5-21 min of one core here, up to 5 GB of memory)::

    PYTHONPATH=/work/rose-src /work/rose-venv/bin/python \\
        benchmarks/peer_runs/make_rose_runs.py rose_coach_smooth --out /work/rose-runs

``--travel-m 2`` makes a short smoke run (written under ``OUT/smoke``, no zone checked);
``--from-npz WALL_S`` checks a run's written NPZ again and writes its JSON without ROSE (the
arrays are written before the checks, so a run whose check failed can be looked at and its
JSON made once the check is understood). Cases: :data:`CASES`. Each writes
``<case>.csv``, ``<case>.truth.json`` and ``<case>.truth.npz`` as the README's section 4
describes, following its recipe: ROSE's public classes only, a Timoshenko UIC60 rail on pads,
150 kg sleepers and ballast, non-linear Hertz contact, Newmark average acceleration with the
contact force iterated (tolerance 1e-4, 12 iterations), ROSE's static start, the first 40 m
of travel not written, off-grid samples dropped.

Zones. The public runs give each zone a ROSE track segment of its own, joined with
``combine_horizontal_tracks``, which puts 0.3 m extra at every joint. Here the track is ONE
uniform mesh (``create_horizontal_track``) and the soft sleepers' ballast springs are a
``Soil`` model part of their own per zone, so every sleeper is exactly at ``i * spacing`` and
the truth says so: ``track.segment_joints`` is false and ``sleeper_x`` is read from the mesh.

Checks done on every run (the README warns a failed contact iteration can pass silently): no
NaN, the wheels never lift off, |accel| far below g, the mean contact force equal to the
static wheel load, the wheel following the loaded rail level (wheel - rail displacement
equals the irregularity), and the dip of the leading wheel's rail receptance (displacement per
unit contact force) centred on each listed zone within a sleeper bay.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path
from typing import Any

import numpy as np

G = 9.81
"""ROSE's gravity, m/s^2."""

ROSE_COMMIT = "b92ff30379eb398b557d29474ac8b7de6ce00d36"

TRACK: dict[str, Any] = {
    "spacing": 0.6,
    "n_sleepers": 700,
    "n_rail_per_sleeper": 2,
    "E": 210e9,
    "nu": 0.3,
    "I": 3.055e-5,
    "A": 76.70e-4,
    "rho": 7850.0,
    "shear_factor": 0.4,
    "k_pad": 250e6,
    "c_pad": 40e3,
    "m_sleeper": 150.0,
    "k_support_nominal": 80e6,
    "c_ballast": 70e3,
}
"""Track per rail seat (README section 2.1), SI."""

VEHICLES: dict[str, dict[str, Any]] = {
    # An intercity coach other than the public one: heavier body, shorter bogie spacing,
    # stiffer suspension, larger wheels (values within the ranges of published passenger
    # coaches; ROSE's own default_trains give 9.95-10.3 m bogie half spacings, 2.5 m wheelbase).
    "coach": {
        "description": "4-axle passenger coach, 44.4 t: body 32.0 t, 2 bogie frames 3.2 t "
        "each, 4 wheelsets 1.5 t each",
        "body_mass_kg": 32000.0,
        "body_pitch_inertia_kgm2": 1.90e6,
        "bogie_frame_mass_kg_each": 3200.0,
        "bogie_frame_pitch_inertia_kgm2_each": 2600.0,
        "wheelset_mass_kg_each": 1500.0,
        "bogie_centre_distance_m": 17.2,
        "wheelbase_m": 2.5,
        "wheel_radius_m": 0.46,
        "secondary_k_N_per_m_per_bogie_per_side": 0.48e6,
        "secondary_c_Ns_per_m_per_bogie_per_side": 30e3,
        "primary_k_N_per_m_per_axlebox": 1.2e6,
        "primary_c_Ns_per_m_per_axlebox": 15e3,
        "dt_s": 2e-4,
    },
    # A loaded freight wagon on Y25-type bogies at 22.5 t axle load (1.8 m wheelbase,
    # 920 mm wheels).
    "freight": {
        "description": "4-axle freight wagon, 90.0 t (22.5 t axle load): body + payload "
        "80.6 t, 2 bogie frames 2.1 t each, 4 wheelsets 1.3 t each",
        "body_mass_kg": 80600.0,
        "body_pitch_inertia_kgm2": 1.70e6,
        "bogie_frame_mass_kg_each": 2100.0,
        "bogie_frame_pitch_inertia_kgm2_each": 900.0,
        "wheelset_mass_kg_each": 1300.0,
        "bogie_centre_distance_m": 11.2,
        "wheelbase_m": 1.8,
        "wheel_radius_m": 0.46,
        "secondary_k_N_per_m_per_bogie_per_side": 30e6,
        "secondary_c_Ns_per_m_per_bogie_per_side": 70e3,
        "primary_k_N_per_m_per_axlebox": 1.9e6,
        "primary_c_Ns_per_m_per_axlebox": 40e3,
        "dt_s": 1.25e-4,
    },
}
"""Whole-vehicle datasheets (per bogie side / per axle box for the springs), SI, and the
ROSE time step each needs (README section 2.3)."""

ZONES_SMOOTH = [(131.4, 135.0, 0.50), (221.4, 228.6, 0.30), (305.4, 311.4, 0.60)]
ZONES_ROUGH = [(146.4, 151.2, 0.40), (190.2, 196.8, 0.55), (232.8, 236.4, 0.35)]
ZONES_ROUGH_2 = [(151.2, 158.4, 0.34), (190.2, 197.4, 0.55), (224.4, 232.2, 0.48)]
ZONES_ROUGH_3 = [(143.4, 148.8, 0.31), (188.4, 192.0, 0.48), (213.6, 220.8, 0.38)]
ZONES_ROUGH_4 = [(145.8, 151.8, 0.44), (170.4, 177.6, 0.59), (215.4, 222.6, 0.56)]
ZONES_ROUGH_5 = [(128.4, 135.0, 0.40), (190.2, 196.8, 0.33), (223.8, 231.0, 0.51)]
ZONES_ROUGH_6 = [(117.0, 123.6, 0.34), (196.8, 204.0, 0.36), (276.6, 284.4, 0.59)]
ZONES_ROUGH_7 = [(112.2, 119.4, 0.50), (205.2, 212.4, 0.43), (297.0, 303.6, 0.58)]
ZONES_ROUGH_8 = [(112.8, 118.8, 0.45), (195.0, 199.2, 0.48), (283.2, 290.4, 0.41)]
ZONES_ROUGH_9 = [(109.2, 114.6, 0.53), (203.4, 209.4, 0.36), (274.2, 282.0, 0.36)]
"""Zones as (first soft sleeper, last soft sleeper, loss of overall support), m, m, -. The
second to fifth rough sets were drawn once each (``numpy.random.default_rng(41)``, ``(43)``,
``(47)`` and ``(53)``: a start within 12 m of 140/180/220 m, 6-13 bays, loss 30-60 %). Sets 4
and 5 as set 3: per zone in turn, start = c + uniform(-12, 12) rounded to the nearest sleeper,
bays = integers(6, 14), loss = uniform(0.30, 0.60) rounded to 2 decimals. Sets 6 and 7
(``(59)``, ``(61)``) are for tracks as long as the public rough runs', so their starts are
drawn about 115/200/285 m, where the public rough runs' zones are, by the same recipe; sets
8 and 9 (``(67)``, ``(71)``) likewise, drawn later to judge a change once."""

IRREGULARITY: dict[str, Any] = {
    "spectrum": "German low disturbance",
    "A_v": 4.032e-7,
    "Omega_c": 0.8246,
    "Omega_r": 0.0206,
    "lambda_min_m": 1.0,
    "lambda_max_m": 120.0,
    "n_waves": 4000,
    "seed": 7310244,
    "taper_start_m": 36.0,
    "taper_end_m": 62.0,
    "units": {"A_v": "m rad", "Omega_c": "rad/m", "Omega_r": "rad/m"},
    "synthesis": "sum of n_waves cosines, Omega uniform between 2pi/lambda_max and "
    "2pi/lambda_min, amplitude sqrt(2 S dOmega), phases uniform from "
    "numpy.random.default_rng(seed).uniform(0, 2pi, n_waves); zero before taper_start, sin^2 "
    "ramp to taper_end; positive up",
    "spectrum_formula": "S(Omega) = A_v Omega_c^2 / ((Omega^2 + Omega_r^2)(Omega^2 + "
    "Omega_c^2)), one-sided",
}
IRREGULARITY_2 = IRREGULARITY | {"seed": 5602683}
IRREGULARITY_3 = IRREGULARITY | {"seed": 5547915}
# Seeds 4 and 5: a fresh generator, not the zones' one continued:
# numpy.random.default_rng(47 / 53).integers(1_000_000, 9_999_999).
IRREGULARITY_4 = IRREGULARITY | {"seed": 1876287}
IRREGULARITY_5 = IRREGULARITY | {"seed": 7806639}
IRREGULARITY_6 = IRREGULARITY | {"seed": 8100619}
IRREGULARITY_7 = IRREGULARITY | {"seed": 4806297}
IRREGULARITY_8 = IRREGULARITY | {"seed": 8045212}
IRREGULARITY_9 = IRREGULARITY | {"seed": 9570772}
"""The rough runs' geometry: the README's spectrum and synthesis, other phase seeds."""

CASES: dict[str, dict[str, Any]] = {
    "rose_coach_smooth": {
        "vehicle": "coach",
        "speed": 31.0,
        "zones": ZONES_SMOOTH,
        "irr": None,
        "n_sleepers": 700,
        "travel_m": 356.0,
    },
    "rose_coach_irr": {
        "vehicle": "coach",
        "speed": 27.0,
        "zones": ZONES_ROUGH,
        "irr": IRREGULARITY,
        "n_sleepers": 560,
        "travel_m": 290.0,
    },
    "rose_freight_irr": {
        "vehicle": "freight",
        "speed": 25.0,
        "zones": ZONES_ROUGH,
        "irr": IRREGULARITY,
        "n_sleepers": 560,
        "travel_m": 290.0,
    },
    "rose2_coach_irr": {
        "vehicle": "coach",
        "speed": 29.0,
        "zones": ZONES_ROUGH_2,
        "irr": IRREGULARITY_2,
        "n_sleepers": 560,
        "travel_m": 290.0,
    },
    "rose2_freight_irr": {
        "vehicle": "freight",
        "speed": 23.0,
        "zones": ZONES_ROUGH_2,
        "irr": IRREGULARITY_2,
        "n_sleepers": 560,
        "travel_m": 290.0,
    },
    "rose3_coach_irr": {
        "vehicle": "coach",
        "speed": 25.0,
        "zones": ZONES_ROUGH_3,
        "irr": IRREGULARITY_3,
        "n_sleepers": 560,
        "travel_m": 290.0,
    },
    "rose3_freight_irr": {
        "vehicle": "freight",
        "speed": 22.0,
        "zones": ZONES_ROUGH_3,
        "irr": IRREGULARITY_3,
        "n_sleepers": 560,
        "travel_m": 290.0,
    },
    "rose4_coach_irr": {
        "vehicle": "coach",
        "speed": 30.0,
        "zones": ZONES_ROUGH_4,
        "irr": IRREGULARITY_4,
        "n_sleepers": 560,
        "travel_m": 290.0,
    },
    "rose4_freight_irr": {
        "vehicle": "freight",
        "speed": 24.0,
        "zones": ZONES_ROUGH_4,
        "irr": IRREGULARITY_4,
        "n_sleepers": 560,
        "travel_m": 290.0,
    },
    "rose5_coach_irr": {
        "vehicle": "coach",
        "speed": 26.0,
        "zones": ZONES_ROUGH_5,
        "irr": IRREGULARITY_5,
        "n_sleepers": 560,
        "travel_m": 290.0,
    },
    "rose5_freight_irr": {
        "vehicle": "freight",
        # 21 m/s stopped in PuggleSolvers' output bookkeeping at the end of the run (no
        # output index after its last stage); 20 m/s does not
        "speed": 20.0,
        "zones": ZONES_ROUGH_5,
        "irr": IRREGULARITY_5,
        "n_sleepers": 560,
        "travel_m": 290.0,
    },
    "rose_coach2_irr": {
        "vehicle": "coach",
        "speed": 30.0,
        "zones": ZONES_ROUGH,
        "irr": IRREGULARITY,
        "n_sleepers": 560,
        "travel_m": 290.0,
    },
    "rose_freight2_irr": {
        "vehicle": "freight",
        "speed": 22.0,
        "zones": ZONES_ROUGH,
        "irr": IRREGULARITY,
        "n_sleepers": 560,
        "travel_m": 290.0,
    },
    "rose2_coach2_irr": {
        "vehicle": "coach",
        "speed": 26.0,
        "zones": ZONES_ROUGH_2,
        "irr": IRREGULARITY_2,
        "n_sleepers": 560,
        "travel_m": 290.0,
    },
    "rose2_freight2_irr": {
        "vehicle": "freight",
        "speed": 24.0,
        "zones": ZONES_ROUGH_2,
        "irr": IRREGULARITY_2,
        "n_sleepers": 560,
        "travel_m": 290.0,
    },
    "rose3_coach2_irr": {
        "vehicle": "coach",
        "speed": 29.0,
        "zones": ZONES_ROUGH_3,
        "irr": IRREGULARITY_3,
        "n_sleepers": 560,
        "travel_m": 290.0,
    },
    "rose3_freight2_irr": {
        "vehicle": "freight",
        "speed": 25.0,
        "zones": ZONES_ROUGH_3,
        "irr": IRREGULARITY_3,
        "n_sleepers": 560,
        "travel_m": 290.0,
    },
    "rose6_coach_irr": {
        "vehicle": "coach",
        "speed": 29.0,
        "zones": ZONES_ROUGH_6,
        "irr": IRREGULARITY_6,
        "n_sleepers": 700,
        "travel_m": 356.0,
    },
    "rose6_freight_irr": {
        "vehicle": "freight",
        "speed": 23.0,
        "zones": ZONES_ROUGH_6,
        "irr": IRREGULARITY_6,
        "n_sleepers": 700,
        "travel_m": 356.0,
    },
    "rose7_coach_irr": {
        "vehicle": "coach",
        "speed": 25.0,
        "zones": ZONES_ROUGH_7,
        "irr": IRREGULARITY_7,
        "n_sleepers": 700,
        "travel_m": 356.0,
    },
    "rose7_freight_irr": {
        "vehicle": "freight",
        "speed": 22.0,
        "zones": ZONES_ROUGH_7,
        "irr": IRREGULARITY_7,
        "n_sleepers": 700,
        "travel_m": 356.0,
    },
    "rose6_coach2_irr": {
        "vehicle": "coach",
        "speed": 26.0,
        "zones": ZONES_ROUGH_6,
        "irr": IRREGULARITY_6,
        "n_sleepers": 700,
        "travel_m": 356.0,
    },
    "rose6_freight2_irr": {
        "vehicle": "freight",
        "speed": 24.0,
        "zones": ZONES_ROUGH_6,
        "irr": IRREGULARITY_6,
        "n_sleepers": 700,
        "travel_m": 356.0,
    },
    "rose7_coach2_irr": {
        "vehicle": "coach",
        "speed": 30.0,
        "zones": ZONES_ROUGH_7,
        "irr": IRREGULARITY_7,
        "n_sleepers": 700,
        "travel_m": 356.0,
    },
    "rose7_freight2_irr": {
        "vehicle": "freight",
        "speed": 25.0,
        "zones": ZONES_ROUGH_7,
        "irr": IRREGULARITY_7,
        "n_sleepers": 700,
        "travel_m": 356.0,
    },
    "rose8_coach_irr": {
        "vehicle": "coach",
        "speed": 28.0,
        "zones": ZONES_ROUGH_8,
        "irr": IRREGULARITY_8,
        "n_sleepers": 700,
        "travel_m": 356.0,
    },
    "rose8_freight_irr": {
        "vehicle": "freight",
        "speed": 22.0,
        "zones": ZONES_ROUGH_8,
        "irr": IRREGULARITY_8,
        "n_sleepers": 700,
        "travel_m": 356.0,
    },
    "rose8_coach2_irr": {
        "vehicle": "coach",
        "speed": 32.0,
        "zones": ZONES_ROUGH_8,
        "irr": IRREGULARITY_8,
        "n_sleepers": 700,
        "travel_m": 356.0,
    },
    "rose8_freight2_irr": {
        "vehicle": "freight",
        "speed": 24.0,
        "zones": ZONES_ROUGH_8,
        "irr": IRREGULARITY_8,
        "n_sleepers": 700,
        "travel_m": 356.0,
    },
    "rose9_coach_irr": {
        "vehicle": "coach",
        "speed": 27.0,
        "zones": ZONES_ROUGH_9,
        "irr": IRREGULARITY_9,
        "n_sleepers": 700,
        "travel_m": 356.0,
    },
    "rose9_freight_irr": {
        "vehicle": "freight",
        "speed": 23.0,
        "zones": ZONES_ROUGH_9,
        "irr": IRREGULARITY_9,
        "n_sleepers": 700,
        "travel_m": 356.0,
    },
    "rose9_coach2_irr": {
        "vehicle": "coach",
        "speed": 31.0,
        "zones": ZONES_ROUGH_9,
        "irr": IRREGULARITY_9,
        "n_sleepers": 700,
        "travel_m": 356.0,
    },
    "rose9_freight2_irr": {
        "vehicle": "freight",
        "speed": 20.0,
        "zones": ZONES_ROUGH_9,
        "irr": IRREGULARITY_9,
        "n_sleepers": 700,
        "travel_m": 356.0,
    },
}
"""The runs: the smooth one alone on the public runs' 700-sleeper track; the two ``_irr``
ones over one shorter track (same zones, same geometry; 560 sleepers, 290 m of travel, to fit
the wagon's small time step into the time there was), each at its own speed. ``rose2_*``,
``rose3_*``, ``rose4_*`` and ``rose5_*``: more such pairs, each on another track (zones,
geometry, speeds); write each to its own folder, the scoring pairs every ``_irr`` run of a
folder. ``*_coach2_irr`` and ``*_freight2_irr``: a second coach and a second wagon pass over
tracks 1-3, 6 and 7 at other speeds (the fleet passes a track many times): written to the
track's folder they make its separation one of four passes. ``rose6_*`` to ``rose9_*``:
pairs on tracks as long as the public rough runs' (700 sleepers, 356 m of travel), each with
a second coach and a second wagon pass; ``rose8_*`` and ``rose9_*`` were made after the
detector's noise re-measure (docs/accuracy.md) to judge it once."""

BODY_START_M = 24.0
CUT_FIRST_M = 40.0
OUT_DT_S = 1e-3
INI_TIME_S = 1e-4
INI_STEPS = 5
TOLERANCE = 1e-4
MAX_ITER = 12


def hertz_g(radius_m: float) -> float:
    """Zhai's Hertz coefficient for a worn tread, m/N^(2/3) (radius in m)."""
    return 4.57e-8 * radius_m**-0.149


def per_rail(full: dict[str, Any]) -> dict[str, Any]:
    """The one-rail model's values: masses and inertias halved, springs per side / per box."""
    w = G * (
        0.25 * full["body_mass_kg"] / 2
        + 0.5 * full["bogie_frame_mass_kg_each"] / 2
        + full["wheelset_mass_kg_each"] / 2
    )
    g = hertz_g(full["wheel_radius_m"])
    return {
        "body_mass_kg": full["body_mass_kg"] / 2,
        "body_pitch_inertia_kgm2": full["body_pitch_inertia_kgm2"] / 2,
        "secondary_k_N_per_m_per_bogie": full["secondary_k_N_per_m_per_bogie_per_side"],
        "secondary_c_Ns_per_m_per_bogie": full["secondary_c_Ns_per_m_per_bogie_per_side"],
        "bogie_frame_mass_kg": full["bogie_frame_mass_kg_each"] / 2,
        "bogie_frame_pitch_inertia_kgm2": full["bogie_frame_pitch_inertia_kgm2_each"] / 2,
        "primary_k_N_per_m_per_wheel": full["primary_k_N_per_m_per_axlebox"],
        "primary_c_Ns_per_m_per_wheel": full["primary_c_Ns_per_m_per_axlebox"],
        "wheel_mass_kg": full["wheelset_mass_kg_each"] / 2,
        "bogie_centre_offsets_from_body_centre_m": [
            0.5 * full["bogie_centre_distance_m"],
            -0.5 * full["bogie_centre_distance_m"],
        ],
        "wheel_offsets_from_bogie_centre_m": [
            0.5 * full["wheelbase_m"],
            -0.5 * full["wheelbase_m"],
        ],
        "static_wheel_load_N": w,
        "hertz_G_m_per_N23": g,
        "hertz_power": 1.5,
        "hertz_k_linearised_at_static_load_N_per_m": 1.5 / g * w ** (1.0 / 3.0),
    }


def lumped(pr: dict[str, Any], full: dict[str, Any]) -> tuple[dict[str, float], dict[str, Any]]:
    """The README's lumped half car (section 2.2) and its notes."""
    k2, c2 = 2 * pr["primary_k_N_per_m_per_wheel"], 2 * pr["primary_c_Ns_per_m_per_wheel"]
    k1, c1 = pr["secondary_k_N_per_m_per_bogie"], pr["secondary_c_Ns_per_m_per_bogie"]
    ks_static = 1.0 / (1.0 / k1 + 1.0 / k2)
    f = float(np.sqrt(2 * ks_static / pr["body_mass_kg"]) / (2 * np.pi))
    w = 2 * np.pi * f
    z = 1.0 / (1.0 / (k1 + 1j * w * c1) + 1.0 / (k2 + 1j * w * c2))
    mu = pr["bogie_frame_mass_kg"] + 2 * pr["wheel_mass_kg"]
    kt = 2 * pr["hertz_k_linearised_at_static_load_N_per_m"]
    d = 0.5 * full["bogie_centre_distance_m"]
    h = {
        "ms": pr["body_mass_kg"],
        "Is": pr["body_pitch_inertia_kgm2"],
        "mu1": mu,
        "mu2": mu,
        "ks1": float(z.real),
        "ks2": float(z.real),
        "cs1": float(z.imag / w),
        "cs2": float(z.imag / w),
        "kt1": kt,
        "kt2": kt,
        "d1": d,
        "d2": d,
        "sensor_x_m": 0.0,
    }
    notes = {
        "f_eval_hz": f,
        "ks_static_series": ks_static,
        "how": "per rail: body -> sprung mass; each bogie -> one 'axle' (frame + its two "
        "wheelsets); suspension = secondary in series with the bogie's two primaries in "
        "parallel, as k + i w c at the body bounce frequency; contact = the bogie's two "
        "linearised Hertz springs in parallel. One possible lumping, not part of the peer model.",
    }
    return h, notes


def ballast_k(support_k: float) -> float:
    """Ballast spring that gives ``support_k`` in series with the pad, N/m."""
    return 1.0 / (1.0 / support_k - 1.0 / TRACK["k_pad"])


def irregularity_profile(x: np.ndarray, irr: dict[str, Any] | None) -> np.ndarray:
    """Unloaded rail geometry at ``x`` (m), m, positive up (README section 2.1)."""
    if irr is None:
        return np.zeros_like(x, dtype=float)
    om = np.linspace(
        2 * np.pi / irr["lambda_max_m"], 2 * np.pi / irr["lambda_min_m"], irr["n_waves"]
    )
    dom = om[1] - om[0]
    s = (
        irr["A_v"]
        * irr["Omega_c"] ** 2
        / ((om**2 + irr["Omega_r"] ** 2) * (om**2 + irr["Omega_c"] ** 2))
    )
    amp = np.sqrt(2 * s * dom)
    phase = np.random.default_rng(irr["seed"]).uniform(0, 2 * np.pi, irr["n_waves"])
    xf = np.asarray(x, dtype=float).ravel()
    z = np.zeros_like(xf)
    for i0 in range(0, xf.size, 20000):
        blk = xf[i0 : i0 + 20000]
        z[i0 : i0 + 20000] = np.cos(np.outer(blk, om) + phase) @ amp
    w = np.clip((xf - irr["taper_start_m"]) / (irr["taper_end_m"] - irr["taper_start_m"]), 0, 1)
    return (np.sin(0.5 * np.pi * w) ** 2 * z).reshape(np.shape(x))


def build(case: dict[str, Any], travel_m: float):
    """The coupled ROSE model of ``case`` and what is needed to read it back."""
    from rose.model.global_system import GlobalSystem
    from rose.model.model_part import ConstraintModelPart, Material, Section
    from rose.model.soil import Soil
    from rose.model.train_model import Bogie, Cart, TrainModel, Wheel
    from rose.model.train_track_interaction import CoupledTrainTrack
    from rose.pre_process.mesh_utils import (
        add_no_displacement_boundary_to_bottom,
        create_horizontal_track,
    )
    from solvers.base_solver import State
    from solvers.newmark_solver import NewmarkImplicitForce

    full = VEHICLES[case["vehicle"]]
    pr = per_rail(full)
    dt = full["dt_s"]
    out_every = int(round(OUT_DT_S / dt))
    v = case["speed"]

    parts, mesh = create_horizontal_track(
        case["n_sleepers"], TRACK["spacing"], 1.0, TRACK["n_rail_per_sleeper"]
    )
    rail, pad, sleeper, soil_all = parts["rail"], parts["rail_pad"], parts["sleeper"], parts["soil"]
    sleeper_x = np.array([n.coordinates[0] for n in sleeper.nodes])
    # One uniform mesh: each zone's ballast springs become a Soil part of their own.
    group = np.zeros(sleeper_x.size, dtype=int)
    for j, (a, b, _) in enumerate(case["zones"], start=1):
        group[(sleeper_x >= a - 1e-6) & (sleeper_x <= b + 1e-6)] = j
    loss = np.zeros(sleeper_x.size)
    soils = []
    for j in range(len(case["zones"]) + 1):
        s = Soil()
        idx = np.flatnonzero(group == j)
        s.elements = [soil_all.elements[i] for i in idx]
        s.nodes = [n for i in idx for n in soil_all.elements[i].nodes]
        k_sup = TRACK["k_support_nominal"] * (1.0 - (case["zones"][j - 1][2] if j else 0.0))
        loss[idx] = case["zones"][j - 1][2] if j else 0.0
        s.stiffness = ballast_k(k_sup)
        s.damping = TRACK["c_ballast"]
        soils.append(s)
    bottoms = [add_no_displacement_boundary_to_bottom(s)["bottom_boundary"] for s in soils]

    material = Material()
    material.youngs_modulus = TRACK["E"]
    material.poisson_ratio = TRACK["nu"]
    material.density = TRACK["rho"]
    section = Section()
    section.area = TRACK["A"]
    section.sec_moment_of_inertia = TRACK["I"]
    section.shear_factor = TRACK["shear_factor"]
    rail.material, rail.section = material, section
    pad.stiffness, pad.damping = TRACK["k_pad"], TRACK["c_pad"]
    sleeper.mass = TRACK["m_sleeper"]
    ends = ConstraintModelPart(x_disp_dof=False, y_disp_dof=True, z_rot_dof=True)
    ends.nodes = [rail.nodes[0], rail.nodes[-1]]

    n_move = int(np.ceil(travel_m / v / dt - 1e-9))
    t_ini = np.linspace(0.0, INI_TIME_S, INI_STEPS)
    t_calc = t_ini[-1] + dt * np.arange(n_move + 1)
    t = np.concatenate([t_ini, t_calc[1:]])
    vel = np.full(t.size, v)
    vel[: t_ini.size] = 0.0

    track = GlobalSystem()
    track.mesh = mesh
    track.time = t
    track.model_parts = [rail, pad, sleeper, ends, *soils, *bottoms]

    train = TrainModel()
    train.time, train.velocities = t, vel
    train.cart_distances = [BODY_START_M]
    cart = Cart()
    cart.bogie_distances = list(pr["bogie_centre_offsets_from_body_centre_m"])
    cart.mass, cart.inertia = pr["body_mass_kg"], pr["body_pitch_inertia_kgm2"]
    cart.stiffness = pr["secondary_k_N_per_m_per_bogie"]
    cart.damping = pr["secondary_c_Ns_per_m_per_bogie"]
    cart.length = full["bogie_centre_distance_m"] + full["wheelbase_m"] + 3.0
    cart.calculate_total_n_dof()
    cart.bogies = [Bogie() for _ in cart.bogie_distances]
    for bogie in cart.bogies:
        bogie.wheel_distances = list(pr["wheel_offsets_from_bogie_centre_m"])
        bogie.mass, bogie.inertia = pr["bogie_frame_mass_kg"], pr["bogie_frame_pitch_inertia_kgm2"]
        bogie.stiffness = pr["primary_k_N_per_m_per_wheel"]
        bogie.damping = pr["primary_c_Ns_per_m_per_wheel"]
        bogie.length = full["wheelbase_m"]
        bogie.calculate_total_n_dof()
        bogie.wheels = [Wheel() for _ in bogie.wheel_distances]
        for wheel in bogie.wheels:
            wheel.mass = pr["wheel_mass_kg"]
    train.carts = [cart]

    # The wheels' chainage as ROSE computes it (TrainModel.calculate_distances).
    travelled = np.cumsum(np.append(0.0, vel[:-1] * np.diff(t)))
    offsets = [
        b + w
        for b in pr["bogie_centre_offsets_from_body_centre_m"]
        for w in pr["wheel_offsets_from_bogie_centre_m"]
    ]
    x_wheels_all = BODY_START_M + travelled[None, :] + np.array(offsets)[:, None]
    # ROSE's prescribed profile enters the contact as -irregularity (its sign is positive down).
    train.irregularities_at_wheels = -irregularity_profile(x_wheels_all, case["irr"])
    train.use_irregularities = False

    coupled = CoupledTrainTrack()
    coupled.train, coupled.track, coupled.rail = train, track, rail
    coupled.time, coupled.initialisation_time = t, t_ini
    coupled.hertzian_contact_coef = pr["hertz_G_m_per_N23"]
    coupled.hertzian_power = 1.5
    coupled.solver = NewmarkImplicitForce(
        state=State(output_interval=out_every), max_iter=MAX_ITER, tolerance=TOLERANCE
    )
    coupled.is_rayleigh_damping = False
    return coupled, {
        "full": full,
        "per_rail": pr,
        "dt": dt,
        "out_every": out_every,
        "sleeper_x": sleeper_x,
        "loss": loss,
        "travelled": travelled,
        "offsets": offsets,
    }


def extract(
    coupled, info: dict[str, Any], case: dict[str, Any], cut_m: float = CUT_FIRST_M
) -> tuple[dict, int]:
    """The written samples (on the 1 ms grid, after the first 40 m) as truth arrays."""
    st = coupled.solver.state
    idx_all = np.asarray(st.output_time_indices)
    keep_rows = np.flatnonzero(idx_all % info["out_every"] == 0)
    dropped = int(idx_all.size - keep_rows.size)
    idx = idx_all[keep_rows]
    x_body_all = BODY_START_M + info["travelled"][idx]
    first = int(np.flatnonzero(x_body_all >= BODY_START_M + cut_m - 1e-9)[0])
    rows, idx = keep_rows[first:], idx[first:]

    train = coupled.train
    cart = train.carts[0]
    cy, cr = cart.nodes[0].index_dof[1], cart.nodes[0].index_dof[2]
    by = [b.nodes[0].index_dof[1] for b in train.bogies]
    wy = [w.nodes[0].index_dof[1] for w in train.wheels]
    u, vv, a = st.u[rows], st.v[rows], st.a[rows]
    n = idx.size
    rail_disp = np.empty((4, n))
    force = np.empty((4, n))
    u_stat = coupled.static_contact_deformation
    for k in range(n):
        d = coupled.get_disp_track_at_wheels(int(idx[k]), u[k])
        rail_disp[:, k] = d
        du = u[k, coupled.train.contact_dofs] + u_stat - d
        force[:, k] = -coupled.calculate_wheel_rail_contact_force(int(idx[k]), du)
    x_body = BODY_START_M + info["travelled"][idx]
    x_wheels = x_body[None, :] + np.array(info["offsets"])[:, None]
    irr_w = irregularity_profile(x_wheels, case["irr"])
    level = irr_w + rail_disp
    half = 0.5 * info["full"]["bogie_centre_distance_m"]
    time_csv = np.round((coupled.time[idx] - coupled.time[idx[0]]) / OUT_DT_S) * OUT_DT_S
    irr_x = np.round(np.arange(0, int(round(info["sleeper_x"][-1] / 0.05)) + 1) * 0.05, 10)
    npz = {
        "t": time_csv,
        "x_body": x_body,
        "x_wheels": x_wheels,
        "wheel_labels": np.array(
            [
                "front bogie front wheelset",
                "front bogie rear wheelset",
                "rear bogie front wheelset",
                "rear bogie rear wheelset",
            ]
        ),
        "rail_disp_wheels": rail_disp,
        "irr_wheels": irr_w,
        "level_wheels": level,
        "x_front_bogie": x_body + half,
        "x_rear_bogie": x_body - half,
        "level_front_bogie": 0.5 * (level[0] + level[1]),
        "level_rear_bogie": 0.5 * (level[2] + level[3]),
        "contact_force_wheels": force,
        "u_wheels": u[:, wy].T,
        "u_bogies": u[:, by].T,
        "acc_bogies": a[:, by].T,
        "body_u": u[:, cy],
        # ROSE's rotation couples a bogie at +d to the body's -theta*d: nose-up is -theta.
        "body_pitch_noseup": -u[:, cr],
        "acc_body": a[:, cy],
        "pitch_rate_body": -vv[:, cr],
        "sleeper_x": info["sleeper_x"],
        "sleeper_k": TRACK["k_support_nominal"] * (1.0 - info["loss"]),
        "sleeper_k_ballast": np.array(
            [ballast_k(TRACK["k_support_nominal"] * (1.0 - x)) for x in info["loss"]]
        ),
        "sleeper_loss": info["loss"],
        "irr_x": irr_x,
        "irr": irregularity_profile(irr_x, case["irr"]),
    }
    return npz, dropped


def checks(npz: dict, pr: dict[str, Any], case: dict[str, Any]) -> list[str]:
    """The README's sanity checks; raises on a failed run, returns the numbers."""
    out = []
    for k in ("acc_body", "pitch_rate_body", "rail_disp_wheels", "contact_force_wheels"):
        if not np.all(np.isfinite(npz[k])):
            raise RuntimeError(f"NaN in {k}: the contact iteration failed")
    fmax = float(np.max(npz["contact_force_wheels"]))
    if fmax >= 0:
        raise RuntimeError(f"a wheel lifted off (contact force {fmax:.0f} N)")
    amax = float(np.max(np.abs(npz["acc_body"])))
    if amax > 0.1 * G:
        raise RuntimeError(f"|accel| {amax:.2f} m/s^2 is not far below g")
    mean_f = -np.mean(npz["contact_force_wheels"], axis=1)
    rel = np.max(np.abs(mean_f / pr["static_wheel_load_N"] - 1.0))
    if rel > 0.01 and case["zones"]:
        raise RuntimeError(f"mean contact force {mean_f} N against {pr['static_wheel_load_N']:.0f}")
    out.append(
        f"contact force mean {', '.join(f'{f / 1e3:.2f}' for f in mean_f)} kN "
        f"(static {pr['static_wheel_load_N'] / 1e3:.3f}); range {-fmax / 1e3:.1f}-"
        f"{-np.min(npz['contact_force_wheels']) / 1e3:.1f} kN; |accel| max {amax:.4f} m/s^2"
    )
    rel_w = npz["u_wheels"][0] - npz["rail_disp_wheels"][0]
    dt = np.diff(npz["t"])
    if not np.allclose(dt, OUT_DT_S, rtol=0, atol=1e-9):
        raise RuntimeError(f"time steps {dt.min()}-{dt.max()} s are not the 1 ms grid")
    rough = np.abs(npz["irr_wheels"][0]) > 0
    if case["irr"] is not None and rough.sum() > 100:
        c = float(np.corrcoef(rel_w[rough], npz["irr_wheels"][0][rough])[0, 1])
        if not c >= 0.999:
            raise RuntimeError(f"wheel - rail does not follow the irregularity (corr {c:.4f})")
        out.append(f"wheel - rail displacement vs irregularity: corr {c:.6f}")
    # The dip under the leading wheel over each zone centres on the zone as listed. The rail
    # displacement per unit contact force (at the static load), so the dynamic load of rough
    # rail does not move the dip.
    x = npz["x_wheels"][0]
    d = npz["rail_disp_wheels"][0] / -npz["contact_force_wheels"][0] * pr["static_wheel_load_N"]
    for a, b, _ in case["zones"]:
        sel = (x > a - 15) & (x < b + 15)
        base = np.median(d[sel & ((x < a - 8) | (x > b + 8))])
        extra = np.clip(base - d[sel], 0, None)
        centre = float(np.sum(x[sel] * extra) / np.sum(extra))
        off = centre - 0.5 * (a + b)
        out.append(
            f"zone {a:.1f}-{b:.1f} m: dip under the leading wheel {1e3 * extra.max():.3f} mm "
            f"deep, centred {off:+.2f} m from the zone's centre"
        )
        if abs(off) > TRACK["spacing"]:
            raise RuntimeError(out[-1])
    return out


def truth_json(name: str, case: dict[str, Any], info: dict, npz: dict, extra: dict) -> dict:
    """The truth JSON, key for key as the public runs'."""
    full, pr = info["full"], info["per_rail"]
    h, notes = lumped(pr, full)
    trk = dict(TRACK)
    trk |= {
        "n_sleepers": case["n_sleepers"],
        "k_ballast_nominal": ballast_k(TRACK["k_support_nominal"]),
        "EI": TRACK["E"] * TRACK["I"],
        "mass_per_m": TRACK["rho"] * TRACK["A"],
        "length_m": float(npz["sleeper_x"][-1]),
        "rail_model": "Timoshenko beam (ROSE Rail), 0.3 m elements, axial DOF fixed at both ends",
        "rail_section": "UIC60",
        "rayleigh_damping": False,
        "segment_joints": False,
        "segment_joints_note": "one uniform mesh (create_horizontal_track); each zone's "
        "ballast springs are a Soil model part of their own, so every sleeper is at i * spacing",
        "units": {
            "E": "Pa",
            "I": "m4",
            "A": "m2",
            "rho": "kg/m3",
            "k_pad": "N/m per rail seat",
            "c_pad": "N s/m per rail seat",
            "m_sleeper": "kg per rail seat",
            "k_support_nominal": "N/m per rail seat, pad+ballast in series",
            "c_ballast": "N s/m per rail seat",
            "spacing": "m",
        },
    }
    zones = []
    for a, b, loss in case["zones"]:
        k = TRACK["k_support_nominal"] * (1 - loss)
        n_sl = int(np.sum((npz["sleeper_x"] >= a - 1e-6) & (npz["sleeper_x"] <= b + 1e-6)))
        zones.append(
            {
                "start_m": a,
                "end_m": b,
                "stiffness_loss": loss,
                "length_m": round(b - a, 6),
                "n_sleepers": n_sl,
                "support_k_N_per_m": k,
                "ballast_k_N_per_m": ballast_k(k),
            }
        )
    n = int(npz["t"].size)
    return {
        "name": name,
        "peer": {
            "code": "ROSE",
            "repository": "https://github.com/PlatypusBytes/ROSE",
            "commit": ROSE_COMMIT,
            "licence": "BSD-3-Clause",
            "solver_package": "PuggleSolvers 1.2.0 (NewmarkImplicitForce)",
        },
        "format": "canonical",
        "columns": ["time_s", "accel_z_mps2", "pitch_rate_radps", "speed_mps"],
        "start_chainage_m": round(float(npz["x_body"][0]), 9),
        "direction": "increasing",
        "speed": case["speed"],
        "sample_rate_hz": 1.0 / OUT_DT_S,
        "n_samples": n,
        "duration_s": round(float(npz["t"][-1]), 6),
        "conventions": {
            "chainage": "ROSE x coordinate; first sleeper at 0.0 m; body centre = cart centre "
            "of gravity",
            "accel_z": "body vertical acceleration at the body centre of gravity, positive up, "
            "gravity excluded",
            "pitch_rate": "body pitch rate, positive nose-up (front end rising), front = "
            "direction of travel",
            "level": "loaded rail level in m, positive up (irregularity positive up + rail "
            "displacement, negative = down)",
        },
        "zones": zones,
        "zone_definition": "start_m/end_m = first/last soft sleeper; loss = fraction of the "
        "overall static support stiffness (pad in series with ballast) removed; only the "
        "ballast spring is softened",
        "track": trk,
        "contact": {
            "model": "non-linear Hertz, F = (delta/G)^1.5, G = 4.57e-8 R^-0.149 (R in m)",
            "G": pr["hertz_G_m_per_N23"],
            "k_linearised_N_per_m": pr["hertz_k_linearised_at_static_load_N_per_m"],
        },
        "vehicle": {
            "description": full["description"],
            "full_vehicle": {
                "total_mass_kg": full["body_mass_kg"]
                + 2 * full["bogie_frame_mass_kg_each"]
                + 4 * full["wheelset_mass_kg_each"],
                **{k: full[k] for k in full if k not in ("description", "dt_s")},
            },
            "per_rail_model": pr,
        },
        "vehicle_full": {
            "description": full["description"],
            "body_mass": full["body_mass_kg"],
            "body_pitch_inertia": full["body_pitch_inertia_kgm2"],
            "bogie_mass": full["bogie_frame_mass_kg_each"],
            "bogie_pitch_inertia": full["bogie_frame_pitch_inertia_kgm2_each"],
            "wheelset_mass": full["wheelset_mass_kg_each"],
            "bogie_half_spacing": 0.5 * full["bogie_centre_distance_m"],
            "wheel_half_base": 0.5 * full["wheelbase_m"],
            "k_secondary_side": full["secondary_k_N_per_m_per_bogie_per_side"],
            "c_secondary_side": full["secondary_c_Ns_per_m_per_bogie_per_side"],
            "k_primary_box": full["primary_k_N_per_m_per_axlebox"],
            "c_primary_box": full["primary_c_Ns_per_m_per_axlebox"],
            "wheel_radius": full["wheel_radius_m"],
        },
        "vehicle_rose_per_rail": {
            "cart_mass": pr["body_mass_kg"],
            "cart_inertia": pr["body_pitch_inertia_kgm2"],
            "cart_stiffness": pr["secondary_k_N_per_m_per_bogie"],
            "cart_damping": pr["secondary_c_Ns_per_m_per_bogie"],
            "bogie_mass": pr["bogie_frame_mass_kg"],
            "bogie_inertia": pr["bogie_frame_pitch_inertia_kgm2"],
            "bogie_stiffness": pr["primary_k_N_per_m_per_wheel"],
            "bogie_damping": pr["primary_c_Ns_per_m_per_wheel"],
            "wheel_mass": pr["wheel_mass_kg"],
            "static_wheel_load_N": pr["static_wheel_load_N"],
            "hertz_G": pr["hertz_G_m_per_N23"],
            "hertz_k_lin": pr["hertz_k_linearised_at_static_load_N_per_m"],
        },
        "half_car_lumped": h,
        "half_car_lumped_notes": notes,
        "irregularity": case["irr"],
        "integration": {
            "solver": "PuggleSolvers NewmarkImplicitForce (beta 0.25, gamma 0.5; Hertz contact "
            "force iterated as an external force)",
            "dt_s": info["dt"],
            "output_every": info["out_every"],
            "cut_first_m": CUT_FIRST_M,
            "tolerance": TOLERANCE,
            "max_iter": MAX_ITER,
            "start": f"static initial state, {INI_TIME_S:g} s at rest, then constant speed; body "
            f"centre starts at {BODY_START_M} m; the first {CUT_FIRST_M} m of travel are not "
            "written",
        },
        **extra,
    }


def write_csv(path: Path, npz: dict, speed: float) -> None:
    """The canonical upload: 1 kHz from 0, 10 significant digits."""
    with path.open("w") as f:
        f.write("time_s,accel_z_mps2,pitch_rate_radps,speed_mps\n")
        for t, a, q in zip(npz["t"], npz["acc_body"], npz["pitch_rate_body"], strict=True):
            f.write(f"{t:.3f},{a:.10g},{q:.10g},{speed:g}\n")


def dropped_off_grid(case: dict[str, Any], out_every: int) -> int:
    """How many samples ROSE's solver adds off the output grid (at its stage boundaries, where
    the time step's rounding changes), as in ``extract``; for ``--from-npz``."""
    dt = VEHICLES[case["vehicle"]]["dt_s"]
    n_move = int(np.ceil(case["travel_m"] / case["speed"] / dt - 1e-9))
    t_ini = np.linspace(0.0, INI_TIME_S, INI_STEPS)
    t = np.concatenate([t_ini, t_ini[-1] + dt * np.arange(1, n_move + 1)])
    stages = np.unique(np.diff(t).round(decimals=15), return_index=True)[1]
    extra = {int(i) for i in stages} | {t.size - 1}
    return sum(1 for i in extra if i % out_every)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("case", choices=sorted(CASES))
    ap.add_argument("--out", type=Path, default=Path("/work/rose-runs"))
    ap.add_argument("--travel-m", type=float, default=None, help="short smoke runs")
    ap.add_argument(
        "--from-npz",
        type=float,
        default=None,
        metavar="WALL_S",
        help="no ROSE: check the run's written NPZ again and write its JSON (ROSE's wall time)",
    )
    args = ap.parse_args()
    case = CASES[args.case]
    if args.from_npz is not None:
        npz = dict(np.load(args.out / f"{args.case}.truth.npz"))
        full = VEHICLES[case["vehicle"]]
        out_every = int(round(OUT_DT_S / full["dt_s"]))
        info = {
            "full": full,
            "per_rail": per_rail(full),
            "dt": full["dt_s"],
            "out_every": out_every,
        }
        wall, dropped = args.from_npz, dropped_off_grid(case, out_every)
    else:
        smoke = args.travel_m is not None
        coupled, info = build(case, args.travel_m if smoke else case["travel_m"])
        t0 = time.perf_counter()
        coupled.main()
        wall = time.perf_counter() - t0
        npz, dropped = extract(coupled, info, case, 0.01 if smoke else CUT_FIRST_M)
        if smoke:
            args.out = args.out / "smoke"
            case = case | {"zones": []}
        args.out.mkdir(parents=True, exist_ok=True)
        # The arrays are written before the checks so a failed run can be looked at; its
        # JSON is written only when every check passes.
        np.savez_compressed(args.out / f"{args.case}.truth.npz", **npz)
        write_csv(args.out / f"{args.case}.csv", npz, case["speed"])
    notes = checks(npz, info["per_rail"], case)
    extra = {"runtime_wall_s": wall, "dropped_off_grid_samples": dropped}
    truth = truth_json(args.case, case, info, npz, extra)
    (args.out / f"{args.case}.truth.json").write_text(json.dumps(truth, indent=1))
    print("\n".join([f"{args.case}: {npz['t'].size} samples, wall {wall / 60:.1f} min", *notes]))


if __name__ == "__main__":
    main()
