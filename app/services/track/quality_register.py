"""Isolated level defects in the register: D1/D2 mean-to-peak values over the track's
speed-class limits (EN 13848-5, ``app.services.track.quality``) as defects of the same record as the
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
from typing import Any

from sqlalchemy import func, select
from sqlalchemy.orm import Session

from app.db.models import Run
from app.services.track.aggregate import CHUNK_POINTS, aggregate_chunk_range
from app.services.track.alignment import GRID_STEP_M
from app.services.track.quality import (
    Analysis,
    defect_next_limit,
    load_line_speeds,
    load_quality_limits,
    pass_values,
    read_levels,
    with_passes,
)
from app.services.views.window import Window
from engine.quality_limits import IsolatedDefect, isolated_defects
from engine.register import (
    Defect,
    Observation,
    RegisterConfig,
    RunCoverage,
    Support,
    build_register,
)
from engine.track_quality import BANDS

BATCH_CHUNKS = 40
"""Chunks analysed at once (10 km), each with a chunk of context either side: a long track's
passes are never all in memory together."""


def isolated_register(
    session: Session,
    track_id: int,
    coverage: Sequence[RunCoverage] = (),
    config: RegisterConfig | None = None,
) -> list[Defect]:
    """The track's isolated level defects as register defects (id ``D1-...``/``D2-...``), each
    with its passes as sightings and ``next_limit``; ``coverage``: the runs' extents (to count
    the runs covering a defect)."""
    stored = aggregate_chunk_range(session, track_id)
    if stored is None:
        return []
    limits, _ = load_quality_limits(session, track_id)
    speeds = load_line_speeds(session, track_id)
    sightings: dict[str, list[Observation]] = {band: [] for band in BANDS}
    found: dict[str, list[tuple[IsolatedDefect, dict[str, Any] | None]]] = {b: [] for b in BANDS}
    loads: dict[int, float | None] = {}
    step = CHUNK_POINTS * GRID_STEP_M
    for c_a in range(stored[0], stored[1] + 1, BATCH_CHUNKS):
        c_b = min(stored[1], c_a + BATCH_CHUNKS - 1)
        inside = Window(c_a * step, (c_b + 1) * step - GRID_STEP_M)
        # the level first, the passes only where it shows a defect: most stretches have none
        lv = read_levels(session, track_id, inside, passes=False)
        if lv is None:
            continue
        q = Analysis(lv, limits, speeds, inside)
        found_here = {
            band: [
                d for d in isolated_defects(q.x, q.filt[band], band, limits, speeds)
                if q.lo <= d.peak_m <= q.hi
            ]
            for band in BANDS
        }  # fmt: skip
        if not any(found_here.values()):
            continue
        lv = with_passes(session, track_id, lv)
        q = Analysis(lv, limits, speeds, inside)
        new = [r for r in lv.passes if r not in loads]
        loads |= dict(
            session.execute(
                select(Run.id, func.coalesce(Run.mean_wheel_force_n, Run.static_wheel_load_n))
                .where(Run.id.in_(new))
            ).all()
        )  # fmt: skip
        for band, here in found_here.items():
            filtered = q.pass_levels(band) if here else {}
            for d in here:
                found[band].append((d, defect_next_limit(d, limits, lv, filtered)))
                sightings[band] += [
                    Observation(
                        rid, when, d.start_m, d.end_m, d.peak_m, value, None, source="isolated",
                        support=(Support(rid, when, loads.get(rid)),),
                        level=limits.level(band, d.speed_kmh, value),
                    )
                    for rid, when, value in pass_values(lv, d.peak_m, filtered)
                ]  # fmt: skip
    out: list[Defect] = []
    for band in BANDS:
        for reg in build_register(sightings[band], coverage, config=config):
            # the register's peak is its sightings' median: the found defect's own peak
            _, nxt = min(found[band], key=lambda f: abs(f[0].peak_m - reg.peak_m))
            out.append(dataclasses.replace(reg, id=f"{band}-{reg.id}", next_limit=nxt))
    return out
