"""Schemas of a track's centerline (issue 11)."""

from __future__ import annotations

from datetime import datetime
from typing import Any

from pydantic import BaseModel, Field

from engine.positioning import MAX_VERTICES

_POSITION: dict[str, Any] = {
    "type": "array",
    "description": "[longitude, latitude] in WGS84 degrees (x before y: longitude -180 to 180, "
    "latitude -90 to 90), an optional third value (height, m) ignored",
    "items": {"type": "number", "minimum": -180, "maximum": 180},
    "minItems": 2,
    "maxItems": 3,
}


def _geojson_object(kind: str, member: str, properties: dict[str, Any]) -> dict[str, Any]:
    """The schema of a GeoJSON object of type ``kind``: its ``type`` member names the kind, and
    ``member`` (of ``properties``, the members besides ``type``) is required with it."""
    return {
        "type": "object",
        "title": kind,
        "required": ["type", member],
        "properties": {"type": {"const": kind}, **properties},
    }


_LINE_STRING = _geojson_object(
    "LineString",
    "coordinates",
    {
        "coordinates": {
            "type": "array",
            "items": _POSITION,
            "minItems": 2,
            "maxItems": MAX_VERTICES,
            "description": "The vertices in order of chainage (at least two distinct ones; "
            "the line may not cross itself)",
        },
    },
)
_FEATURE = _geojson_object(
    "Feature",
    "geometry",
    {
        "geometry": _LINE_STRING,
        "properties": {
            "type": ["object", "null"],
            "description": "Free properties; start_chainage_m (m) is the chainage of the "
            "first vertex (else the query parameter, else 0)",
            "properties": {"start_chainage_m": {"type": "number"}},
        },
    },
)
CENTERLINE_GEOJSON_SCHEMA: dict[str, Any] = {
    "title": "CenterlineGeoJson",
    "description": "A GeoJSON LineString in WGS84 [longitude, latitude], bare, as a Feature or "
    "as a FeatureCollection of exactly one Feature. Its chainage starts at start_chainage_m "
    "and grows with the geodesic length along the line.",
    "oneOf": [
        _LINE_STRING,
        _FEATURE,
        _geojson_object(
            "FeatureCollection",
            "features",
            {"features": {"type": "array", "items": _FEATURE, "minItems": 1, "maxItems": 1}},
        ),
    ],
}
"""The JSON body of ``PUT /tracks/{track}/centerline`` (documentation: the engine reads and
checks it, naming the vertex at fault)."""

CENTERLINE_CSV_SCHEMA: dict[str, Any] = {
    "type": "string",
    "title": "CenterlineCsv",
    "description": "CSV text with a header naming chainage_m (or chainage), lat and lon (or "
    "latitude, longitude, lng ...), then one vertex per line: chainage in m, strictly "
    "increasing (a jump at a repeated point is a chainage equation) and within 5 % of the "
    "line's geodesic length; latitude and longitude in WGS84 degrees. Example lines: "
    "'chainage_m,lat,lon', '11900,50.0,10.0', '11950,50.00039,10.00026'.",
}
"""The CSV body of ``PUT /tracks/{track}/centerline``."""


class CenterlinePublic(BaseModel):
    """A stored centerline's figures (the line itself: ``GET .../centerline``)."""

    track_id: int
    n_vertices: int
    length_m: float = Field(description="Length along the line, m")
    start_chainage_m: float = Field(description="Chainage of the first vertex, m")
    end_chainage_m: float = Field(description="Chainage of the last vertex, m")
    source: str = Field(description="geojson or csv")
    updated_at: datetime | None
