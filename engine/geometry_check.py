"""Whether one pass's stiffness-loss figures are valid: is the rail smooth at the noise level?

One loaded pass cannot tell a geometric dip of the rail from a soft spot (docs/method.md,
"When single-pass stiffness figures stay valid"). Where the pass itself shows the rail
smooth at the noise level (straight-rail simulations, the shared samples, the paper's case),
its figures stay valid; otherwise the pipeline withholds them.
"""

from __future__ import annotations

import math

from .results import GeometryCheck, ProcessResult

SMOOTH_RAIL_SIGMA_MM = 0.05
"""Largest robust spread (mm) of a single pass's residual (level minus its 40 m baseline, in
the 3-40 m band) for which the rail counts as smooth at the noise level: single-pass
stiffness-loss figures stay valid. Measured (docs/method.md, "Rail geometry"): straight-rail
runs give 0.011-0.016 mm (shared samples) and up to 0.036 mm at four times their sensor
noise; a geometry of 0.05 mm SD moves a zone's fitted loss by about 5-8 pp; real track
(German low-disturbance, FRA class 6) gives 1-2 mm."""

SMOOTH_RAIL_MESSAGE = (
    "rail not smooth at the noise level: a dip may be rail geometry, so no stiffness-loss "
    "figure from this pass alone (needs passes with different wheel loads or a survey)"
)


def is_smooth_rail(
    result: ProcessResult | float, threshold_mm: float = SMOOTH_RAIL_SIGMA_MM
) -> GeometryCheck:
    """Whether one pass shows the rail smooth at the noise level (single-pass figures valid).

    Parameters
    ----------
    result : ProcessResult or float
        A processed run, or directly the robust spread of its residual, mm.
    threshold_mm : float
        Largest robust spread of the residual (level minus 40 m baseline) of a smooth rail, mm.

    Returns
    -------
    GeometryCheck
        ``smooth`` true when the spread is at or below the threshold; a message otherwise.
    """
    if isinstance(result, ProcessResult):
        sigma = float(result.extras.get("residual_sigma_mm", float("nan")))
    else:
        sigma = float(result)
    smooth = bool(math.isfinite(sigma) and sigma <= threshold_mm)
    return GeometryCheck(smooth, sigma, threshold_mm, None if smooth else SMOOTH_RAIL_MESSAGE)
