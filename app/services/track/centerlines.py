"""Track centerlines: reading, storing, and placing runs by their GNSS fixes.

A centerline is read by the engine (:mod:`engine.positioning`) from GeoJSON or CSV; its
problems become :class:`Invalid` naming the vertex or line. Placing a run turns the engine's
positioning errors into :class:`Invalid` too (the run is not stored).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import Any

from sqlalchemy import select
from sqlalchemy.orm import Session

from app.db.models import Track, TrackCenterline
from app.services.errors import Invalid, NotFound
from engine.budget import TimeBudget
from engine.errors import BudgetExceeded
from engine.positioning import (
    Centerline,
    CenterlineError,
    FixesBesideLine,
    FixesOffLine,
    Placement,
    PositioningError,
    centerline_from_csv,
    centerline_from_geojson,
    place_log,
)
from engine.runlog import RunLog

GEOJSON_TYPES = ("application/geo+json", "application/json")
CSV_TYPES = ("text/csv",)
CONTENT_TYPES = GEOJSON_TYPES + CSV_TYPES
"""Media types a centerline may be sent as."""


def _invalid(exc: CenterlineError) -> Invalid:
    return Invalid(str(exc), field=exc.field or "body", row=exc.row, kind=type(exc).__name__)


MAX_INT_DIGITS = 30
"""Most digits of an integer in a centerline's JSON: degrees and metres need a handful; Python
refuses to convert more than 4 300, and a 1 MB body could hold 250 000."""


def _json_int(text: str) -> int:
    if len(text.lstrip("-")) > MAX_INT_DIGITS:
        raise Invalid(
            f"the centerline's JSON holds an integer of {len(text.lstrip('-'))} digits (at "
            f"most {MAX_INT_DIGITS}): coordinates are degrees and chainage is metres",
            field="body",
        )
    return int(text)


def read_centerline(
    data: bytes, content_type: str, start_chainage_m: float | None = None
) -> tuple[Centerline, str]:
    """A centerline from a request body; returns it and its source (``geojson`` or ``csv``).

    Raises
    ------
    Invalid
        The body is not UTF-8 text, not JSON (for GeoJSON types), or the line is refused by
        the engine (naming the vertex, line or field); ``start_chainage_m`` with a CSV.
    """
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError:
        raise Invalid("the centerline is not UTF-8 text", field="body") from None
    try:
        if content_type in CSV_TYPES:
            if start_chainage_m is not None:
                raise Invalid(
                    "start_chainage_m is for GeoJSON lines: a CSV gives the chainage of every "
                    "vertex in its chainage_m column",
                    field="start_chainage_m",
                )
            return centerline_from_csv(text), "csv"
        try:
            obj = json.loads(text, parse_int=_json_int)
        except json.JSONDecodeError as exc:
            raise Invalid(
                f"the centerline is not valid JSON: {exc.msg} at line {exc.lineno}, column "
                f"{exc.colno}",
                field="body",
                row=exc.lineno,
            ) from None
        except RecursionError:
            raise Invalid(
                "the centerline's JSON is nested too deeply to read: a GeoJSON LineString is "
                "at most four levels deep (FeatureCollection, Feature, coordinates, position)",
                field="body",
            ) from None
        return centerline_from_geojson(obj, start_chainage_m), "geojson"
    except CenterlineError as exc:
        raise _invalid(exc) from None


def store_centerline(
    session: Session, track: Track, line: Centerline, source: str
) -> tuple[TrackCenterline, bool]:
    """Create or replace the track's centerline (the caller commits); returns the row and
    whether it is new."""
    row = session.get(TrackCenterline, track.id)
    created = row is None
    if row is None:
        row = TrackCenterline(track_id=track.id)
        session.add(row)
    row.n_vertices = line.n_vertices
    row.length_m = line.length_m
    row.start_chainage_m = line.start_chainage_m
    row.end_chainage_m = line.end_chainage_m
    row.source = source
    row.data = line.to_dict()
    return row, created


def centerline_row(session: Session, track: Track) -> TrackCenterline:
    """The track's stored centerline; NotFound when it has none."""
    row = session.get(TrackCenterline, track.id)
    if row is None:
        raise NotFound(
            f"track {track.name!r} has no centerline (PUT /api/v1/tracks/{{track}}/centerline "
            "with a GeoJSON LineString or a CSV chainage_m,lat,lon)",
            field="track",
        )
    return row


def load_centerline(session: Session, track_id: int) -> Centerline | None:
    """The track's centerline as the engine's object, None when it has none."""
    row = session.get(TrackCenterline, track_id)
    return Centerline.from_dict(row.data) if row is not None else None


def with_centerline(session: Session, track_ids: list[int]) -> set[int]:
    """Those of the tracks ``track_ids`` that have a centerline."""
    if not track_ids:
        return set()
    rows = session.execute(
        select(TrackCenterline.track_id).where(TrackCenterline.track_id.in_(track_ids))
    ).all()
    return {int(t) for (t,) in rows}


def delete_centerline(session: Session, track: Track) -> None:
    """Remove the track's centerline (NotFound when it has none; the caller commits). Runs
    placed by it keep their chainage."""
    session.delete(centerline_row(session, track))


def as_geojson(row: TrackCenterline) -> dict[str, Any]:
    """A stored centerline as a GeoJSON Feature: the line, its chainage per vertex and its
    figures in ``properties``."""
    d = row.data
    return {
        "type": "Feature",
        "geometry": {
            "type": "LineString",
            "coordinates": [[lo, la] for lo, la in zip(d["lon_deg"], d["lat_deg"], strict=True)],
        },
        "properties": {
            "start_chainage_m": row.start_chainage_m,
            "end_chainage_m": row.end_chainage_m,
            "length_m": row.length_m,
            "n_vertices": row.n_vertices,
            "source": row.source,
            "chainage_m": d["chainage_m"],
            "updated_at": row.updated_at.isoformat() if row.updated_at else None,
        },
    }


def plan_view(row: TrackCenterline) -> dict[str, Any]:
    """The line in local metres (east, north) with its chainage per vertex: for a plan plot
    (no map tiles needed)."""
    line = Centerline.from_dict(row.data)
    x, y = line.plane()
    return {
        "x_m": x.round(3).tolist(),
        "y_m": y.round(3).tolist(),
        "chainage_m": line.chainage_m.tolist(),
        "lon_deg": line.lon_deg.tolist(),
        "lat_deg": line.lat_deg.tolist(),
    }


def points_on_plan(row: TrackCenterline, chainages: list[float]) -> list[tuple[float, float]]:
    """Local metres (east, north) of the points at ``chainages`` (m) on the line."""
    line = Centerline.from_dict(row.data)
    x, y = line.point_at(chainages)
    return [(round(float(a), 3), round(float(b), 3)) for a, b in zip(x, y, strict=True)]


@dataclass(frozen=True)
class Placed:
    """A run placed by its fixes: the log with the fitted chainage column, and the fit."""

    log: RunLog
    placement: Placement


def place_by_gnss(log: RunLog, line: Centerline, budget: TimeBudget | None = None) -> Placed:
    """Place a run on the track's centerline by its GNSS fixes (the caller holds a processing
    slot: the fit's work is bounded, but it is a processing stage like the inversion).

    Raises
    ------
    Invalid
        The fixes are missing, too few, too far off the line (``median_offset_m`` given),
        steadily beside it (``lateral_offset_m``: a neighbouring track) or do not follow it
        (another line, the wrong track), or ``budget`` ran out; nothing is stored.
    """
    try:
        placed, fit = place_log(log, line, budget=budget)
    except PositioningError as exc:
        facts: dict[str, Any] = {"field": "file", "kind": type(exc).__name__}
        if isinstance(exc, FixesOffLine):
            facts["median_offset_m"] = round(exc.median_offset_m, 1)
        if isinstance(exc, FixesBesideLine):
            facts["lateral_offset_m"] = round(exc.lateral_offset_m, 1)
        raise Invalid(str(exc), **facts) from None
    except BudgetExceeded as exc:
        raise Invalid.from_engine(exc) from None
    return Placed(placed, fit)
