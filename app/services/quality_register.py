"""Isolated level defects in the register: D1/D2 mean-to-peak values over the track's
speed-class limits (EN 13848-5, ``app.services.quality``) as defects of the same record as the
soft spots (``engine.register``, source ``isolated``).

Each pass over a defect is a sighting: its value there (largest |level| of its own filtered
level within ``PEAK_MATCH_M`` of the peak, mm, as ``depth_mm``) and the level that value
reaches by the limits of the line speed. The register then gives the defect its status, trend
and level from the latest pass; the predicted date of the next level is the quality answer's.
The defects are found on the track's analysed level (unloaded where separable), the sightings
are each pass's loaded level: near a limit the two may name different levels.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

from sqlalchemy import func, select
from sqlalchemy.orm import Session

from app.db.models import Run
from engine.quality_limits import isolated_defects
from engine.register import (
    Defect,
    Observation,
    RegisterConfig,
    RunCoverage,
    Support,
    build_register,
)
from engine.track_quality import BANDS

from .quality import (
    Analysis,
    defect_next_limit,
    load_line_speeds,
    load_quality_limits,
    pass_values,
    read_levels,
)
from .window import Window


def isolated_register(
    session: Session,
    track_id: int,
    coverage: Sequence[RunCoverage] = (),
    config: RegisterConfig | None = None,
) -> list[Defect]:
    """The track's isolated level defects as register defects (id ``D1-...``/``D2-...``), each
    with its passes as sightings and ``next_limit``; ``coverage``: the runs' extents (to count
    the runs covering a defect)."""
    lv = read_levels(session, track_id, Window())
    if lv is None:
        return []
    limits, _ = load_quality_limits(session, track_id)
    q = Analysis(lv, limits, load_line_speeds(session, track_id), Window())
    loads = dict(
        session.execute(
            select(Run.id, func.coalesce(Run.mean_wheel_force_n, Run.static_wheel_load_n)).where(
                Run.id.in_(list(lv.passes))
            )
        ).all()
    )
    out: list[Defect] = []
    for band in BANDS:
        found = isolated_defects(q.x, q.filt[band], band, limits, q.speeds)
        filtered = q.pass_levels(band) if found else {}
        sightings = [
            Observation(
                rid, when, d.start_m, d.end_m, d.peak_m, value, None, source="isolated",
                support=(Support(rid, when, loads.get(rid)),),
                level=limits.level(band, d.speed_kmh, value),
            )
            for d in found
            for rid, when, value in pass_values(lv, d.peak_m, filtered)
        ]  # fmt: skip
        for reg in build_register(sightings, coverage, config=config):
            # the register's peak is its sightings' median: the found defect's own peak
            src = min(found, key=lambda d: abs(d.peak_m - reg.peak_m))
            nxt = defect_next_limit(src, limits, lv, filtered)
            out.append(dataclasses.replace(reg, id=f"{band}-{reg.id}", next_limit=nxt))
    return out
