"""Schemas of a track's centerline (issue 11)."""

from __future__ import annotations

from datetime import datetime

from pydantic import BaseModel, Field


class CenterlinePublic(BaseModel):
    """A stored centerline's figures (the line itself: ``GET .../centerline``)."""

    track_id: int
    n_vertices: int
    length_m: float = Field(description="Length along the line, m")
    start_chainage_m: float = Field(description="Chainage of the first vertex, m")
    end_chainage_m: float = Field(description="Chainage of the last vertex, m")
    source: str = Field(description="geojson or csv")
    updated_at: datetime | None
