"""A run log placed on a centerline: its chainage column written from the fitted odometer."""

from __future__ import annotations

import dataclasses

from ..budget import TimeBudget
from ..runlog import RunLog
from .centerline import Centerline
from .errors import NoFixes
from .fit import MAX_OFFSET_M, Placement, place_run


def place_log(
    log: RunLog,
    centerline: Centerline,
    *,
    max_offset_m: float = MAX_OFFSET_M,
    budget: TimeBudget | None = None,
) -> tuple[RunLog, Placement]:
    """Place a run by its GNSS fixes: the log with its chainage column set from the fit.

    The odometer is the log's chainage column if it has one, else its integrated speed. The
    returned log's ``chainage_m`` is the fitted body-centre chainage at every sample (m, on
    the centerline's chainage) and its speed is scaled by the fitted local odometer scale,
    so the inversion sees the distances the fixes measured.

    Parameters
    ----------
    log : RunLog
        A run with ``lat_deg``/``lon_deg`` fixes.
    centerline : Centerline
        The track's centerline.
    max_offset_m : float
        Farthest a fix may lie from the line and still be used, m.
    budget : TimeBudget, optional
        Checked between the fit's stages.

    Returns
    -------
    (RunLog, Placement)
        The placed log and the fit (direction, scale, residual, fixes used/rejected).

    Raises
    ------
    PositioningError
        See :func:`~engine.positioning.fit.place_run`; :class:`NoFixes` when the log carries
        no latitude/longitude at all.
    """
    if log.lat_deg is None or log.lon_deg is None:
        raise NoFixes(
            "the log has no latitude/longitude columns: give start_chainage_m, or GNSS fixes "
            "(columns such as lat, lon) to place the run on the centerline"
        )
    odo = log.distance()
    fit = place_run(
        centerline, log.time_s, odo, log.lat_deg, log.lon_deg, max_offset_m=max_offset_m,
        budget=budget,
    )  # fmt: skip
    speed = log.speed_mps * fit.local_scale(odo) if log.speed_mps is not None else None
    placed = dataclasses.replace(log, chainage_m=fit.chainage(odo), speed_mps=speed)
    return placed, fit
