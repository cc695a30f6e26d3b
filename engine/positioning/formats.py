"""Reading a centerline: GeoJSON (LineString, Feature, one-feature FeatureCollection) or CSV
``chainage_m,lat,lon`` (explicit chainage per vertex)."""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from ..logio.roles import role_aliases
from .centerline import MAX_VERTICES, Centerline, geodesic_chainage
from .errors import CenterlineError

CHAINAGE_LENGTH_TOLERANCE = 0.05
"""Largest relative difference between a CSV's chainage and the line's geodesic length (over
the segments that have a length: a chainage equation is a jump at a repeated point). Surveyed
chainage follows the ground length to well under 1 %, a polyline's chords shorten its curves
by less than 0.5 %; beyond 5 % the column is in another unit or belongs to another line, and
the odometer fit (scale 0.85-1.15) would otherwise absorb the difference unseen."""


def _number(value: Any, what: str, row: int | None = None) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise CenterlineError(f"{what} must be a number, got {value!r}", field=what, row=row)
    x = float(value)
    if not math.isfinite(x):
        raise CenterlineError(f"{what} must be a finite number, got {value!r}", field=what)
    return x


def _line_string(obj: Any) -> tuple[Any, Mapping[str, Any]]:
    """The LineString geometry of a GeoJSON object and the properties that came with it."""
    if not isinstance(obj, Mapping):
        raise CenterlineError(
            f"a centerline must be a GeoJSON object, got {type(obj).__name__}", field="type"
        )
    kind = obj.get("type")
    if kind == "FeatureCollection":
        feats = obj.get("features")
        if not isinstance(feats, list) or len(feats) != 1:
            n = len(feats) if isinstance(feats, list) else 0
            raise CenterlineError(
                f"a FeatureCollection centerline must hold exactly one feature, it holds {n}",
                field="features",
            )
        return _line_string(feats[0])
    if kind == "Feature":
        props = obj.get("properties") or {}
        if not isinstance(props, Mapping):
            raise CenterlineError("the Feature's properties must be an object", field="properties")
        geom, _ = _line_string(obj.get("geometry"))
        return geom, props
    if kind == "LineString":
        return obj, {}
    if kind == "MultiLineString":
        raise CenterlineError(
            "a MultiLineString is not a centerline: join its parts into one LineString in "
            "order of chainage, or give a CSV chainage_m,lat,lon for lines with chainage jumps",
            field="type",
        )
    raise CenterlineError(
        f"a centerline is a GeoJSON LineString (bare, as a Feature or in a one-feature "
        f"FeatureCollection), got type {kind!r}",
        field="type",
    )


def centerline_from_geojson(obj: Any, start_chainage_m: float | None = None) -> Centerline:
    """A centerline from parsed GeoJSON in WGS84 ``[longitude, latitude]`` positions.

    Parameters
    ----------
    obj : dict
        A ``LineString``, a ``Feature`` holding one, or a ``FeatureCollection`` of exactly one
        such ``Feature``. Positions may carry a third (height) value, which is ignored.
    start_chainage_m : float, optional
        Chainage of the first vertex, m; else the Feature's property ``start_chainage_m``;
        else 0. The chainage grows with the geodesic (WGS84) length along the line.

    Raises
    ------
    CenterlineError
        Naming what is wrong (type, position, vertex, a start chainage given twice with two
        values) and every problem :class:`Centerline` checks.
    """
    geom, props = _line_string(obj)
    coords = geom.get("coordinates")
    if not isinstance(coords, list):
        raise CenterlineError("the LineString has no coordinates list", field="coordinates")
    if len(coords) > MAX_VERTICES:
        raise CenterlineError(
            f"the centerline has {len(coords)} vertices, more than the {MAX_VERTICES} allowed",
            field="coordinates",
        )
    lon = np.empty(len(coords))
    lat = np.empty(len(coords))
    for i, pos in enumerate(coords):
        if not isinstance(pos, list | tuple) or len(pos) not in (2, 3):
            raise CenterlineError(
                f"vertex {i + 1} is {pos!r}: a position is [longitude, latitude] in degrees",
                field="coordinates",
                row=i + 1,
            )
        lon[i] = _number(pos[0], "coordinates", i + 1)
        lat[i] = _number(pos[1], "coordinates", i + 1)
    prop = props.get("start_chainage_m")
    if prop is not None:
        prop = _number(prop, "start_chainage_m")
    if start_chainage_m is not None and prop is not None and prop != start_chainage_m:
        raise CenterlineError(
            f"start_chainage_m is given twice with different values ({start_chainage_m:g} m "
            f"as a parameter, {prop:g} m as the Feature's property): give it once",
            field="start_chainage_m",
        )
    start = start_chainage_m if start_chainage_m is not None else (prop or 0.0)
    if len(coords) < 2:
        raise CenterlineError(
            f"the centerline has {len(coords)} point{'s' if len(coords) != 1 else ''}: "
            "a line needs at least two",
            field="coordinates",
        )
    return Centerline(lon, lat, geodesic_chainage(lon, lat, start))


def _column(names: list[str], role: str, fallback: tuple[str, ...] = ()) -> int | None:
    wanted = role_aliases(role) | set(fallback)
    found = [j for j, n in enumerate(names) if n.strip().lower() in wanted]
    return found[0] if len(found) == 1 else None


def centerline_from_csv(text: str) -> Centerline:
    """A centerline from CSV text with a header naming ``chainage_m``, ``lat`` and ``lon``.

    Latitude and longitude are recognised under the run logs' names for them (``lat``,
    ``latitude``, ``lon``, ``lng``, ``longitude`` ...), in WGS84 degrees; the chainage column is
    ``chainage_m`` (or ``chainage``), m, strictly increasing (it may jump: chainage equations).

    Raises
    ------
    CenterlineError
        A missing column, a field that is not a number (naming the line), a row the csv
        module cannot read (a field over its 128 KB limit), a chainage that departs from the
        line's geodesic length by more than :data:`CHAINAGE_LENGTH_TOLERANCE`, and every
        problem :class:`Centerline` checks (lines are named as vertices, vertex 1 being line 2).
    """
    reader = csv.reader(io.StringIO(text.lstrip("\ufeff")))
    try:
        rows = [r for r in reader if r and any(c.strip() for c in r)]
    except csv.Error as exc:
        # the csv module's own limits (a field over 128 KB, a NUL byte): no centerline has them
        raise CenterlineError(
            f"line {reader.line_num}: not a readable CSV row ({exc}); expected numbers "
            "chainage_m,lat,lon",
            field="body",
            row=reader.line_num,
        ) from None
    if not rows:
        raise CenterlineError("the CSV is empty: expected a header chainage_m,lat,lon", row=1)
    names = [c.strip() for c in rows[0]]
    cols = {
        "chainage_m": _column(names, "chainage", ("chainage_m", "chainage")),
        "lat": _column(names, "lat"),
        "lon": _column(names, "lon"),
    }
    missing = [k for k, j in cols.items() if j is None]
    if missing:
        raise CenterlineError(
            f"the CSV needs the columns chainage_m, lat and lon (WGS84 degrees); "
            f"not found: {', '.join(missing)}; columns found: {', '.join(map(repr, names))}",
            field=missing[0],
            row=1,
        )
    data = rows[1:]
    if len(data) > MAX_VERTICES:
        raise CenterlineError(
            f"the centerline has {len(data)} vertices, more than the {MAX_VERTICES} allowed",
            field="coordinates",
        )
    out = {k: np.empty(len(data)) for k in cols}
    for i, r in enumerate(data):
        for k, j in cols.items():
            assert j is not None
            try:
                out[k][i] = float(r[j])
            except (IndexError, ValueError):
                cell = r[j] if j < len(r) else ""
                raise CenterlineError(
                    f"line {i + 2}: column {names[j]!r} holds {cell!r}, not a number",
                    field=k,
                    row=i + 2,
                ) from None
    if len(data) < 2:
        raise CenterlineError(
            f"the centerline has {len(data)} point{'s' if len(data) != 1 else ''}: a line "
            "needs at least two",
            field="coordinates",
        )
    line = Centerline(out["lon"], out["lat"], out["chainage_m"])
    _check_chainage_length(line)
    return line


def _check_chainage_length(line: Centerline) -> None:
    step = np.diff(geodesic_chainage(line.lon_deg, line.lat_deg))
    moving = step > 0
    length = float(step.sum())
    along = float(np.diff(line.chainage_m)[moving].sum())
    if abs(along / length - 1.0) > CHAINAGE_LENGTH_TOLERANCE:
        raise CenterlineError(
            f"the chainage_m column runs {along:.1f} m along the line but the line is "
            f"{length:.1f} m long (geodesic, WGS84; jumps at repeated points, chainage "
            f"equations, not counted): {100 * (along / length - 1):+.0f} %, beyond the "
            f"{100 * CHAINAGE_LENGTH_TOLERANCE:.0f} % allowed. Is the chainage in metres, and "
            "does it belong to this line?",
            field="chainage_m",
        )
