"""A track's quality answer as CSV and as GeoJSON on its centerline (opens in QGIS).

Units: chainage m, levels mm; coordinates WGS84 degrees, ``[lon, lat]``.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray
from sqlalchemy.orm import Session

from app.db.models import Track
from app.services.errors import NotFound
from app.services.track.centerlines import load_centerline
from app.services.track.quality import track_quality
from app.services.views.window import Window

QUALITY_CSV_COLUMNS = (
    "start_m", "end_m", "d1_sd_mm", "d2_sd_mm", "n_passes", "days_since_last_pass",
    "repeatability_d1_mm", "speed_kmh", "quality_class", "basis", "d2_level",
)  # fmt: skip


def quality_csv(answer: dict[str, Any]) -> str:
    """The sections as CSV (one row each), then a blank line and the defects; first a ``#``
    line when D2 leaves out runs still waiting for their long level."""
    waiting = answer.get("d2_waiting_runs") or []
    lines = [f"# D2 leaves out run id {', '.join(map(str, waiting))}: its long level is still "
             "being inverted"] if waiting else []  # fmt: skip
    lines.append(",".join(QUALITY_CSV_COLUMNS))
    for s in answer["sections"]:
        lines.append(",".join("" if s[c] is None else str(s[c]) for c in QUALITY_CSV_COLUMNS))
    lines.append("")
    cols = ("peak_m", "start_m", "end_m", "band", "value_mm", "level", "speed_kmh", "basis")
    lines.append(",".join(cols))
    for d in answer["defects"]:
        lines.append(",".join("" if d[c] is None else str(d[c]) for c in cols))
    return "\n".join(lines) + "\n"


def _lonlat(line: Any, chainage: NDArray[np.float64]) -> list[list[float]]:
    # vertices are dense (tens of metres): linear interpolation of degrees between them is
    # within millimetres of the geodesic
    lon = np.interp(chainage, line.chainage_m, line.lon_deg)
    lat = np.interp(chainage, line.chainage_m, line.lat_deg)
    return [[round(float(a), 8), round(float(b), 8)] for a, b in zip(lon, lat, strict=True)]


def quality_geojson(
    session: Session, track: Track, section_m: float = 200.0, window: Window | None = None
) -> dict[str, Any]:
    """Sections (LineString) and isolated defects (Point) on the track's centerline, WGS84
    ``[lon, lat]``; NotFound when the track has no centerline."""
    line = load_centerline(session, track.id)
    if line is None:
        raise NotFound(
            f"track {track.name!r} has no centerline: upload one (PUT /tracks/{{track}}/"
            "centerline) to place its quality on a map",
            field="track",
        )
    answer = track_quality(session, track, section_m, window=window)
    lo, hi = line.start_chainage_m, line.end_chainage_m
    features: list[dict[str, Any]] = []
    for s in answer["sections"]:
        a, b = max(s["start_m"], lo), min(s["end_m"], hi)
        if b <= a:
            continue
        n = max(2, int(math.ceil((b - a) / 10.0)) + 1)
        features.append({
            "type": "Feature",
            "geometry": {"type": "LineString", "coordinates": _lonlat(line, np.linspace(a, b, n))},
            "properties": {"kind": "section"} | {k: v for k, v in s.items() if k != "next_class"},
        })  # fmt: skip
    for d in answer["defects"]:
        if not (lo <= d["peak_m"] <= hi):
            continue
        features.append({
            "type": "Feature",
            "geometry": {"type": "Point", "coordinates": _lonlat(line, np.array([d["peak_m"]]))[0]},
            "properties": {"kind": "defect"} | {k: v for k, v in d.items()
                                                if k not in ("limits_mm", "next_limit")},
        })  # fmt: skip
    return {"type": "FeatureCollection", "features": features}
