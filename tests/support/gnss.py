"""Synthetic centerlines and GNSS fixes for the positioning tests (engine, API, browser).

The line is drawn in a local transverse Mercator plane of its own (not the one the engine
builds) and written as WGS84 lon/lat: a straight, a 1 200 m radius bend, a straight. Fixes are
the true body-centre position plus white noise and a slowly wandering bias (an
Ornstein-Uhlenbeck process per axis), at a GNSS rate, NaN between fixes.
"""

from __future__ import annotations

import dataclasses
import io
from typing import Any

import numpy as np
from numpy.typing import NDArray
from pyproj import CRS, Transformer

from engine.logio import write_run_csv
from engine.runlog import RunLog

LON0, LAT0 = 10.0, 50.0
LINE_START_CHAINAGE_M = 11_900.0
RUN_OFFSET_M = 100.0
"""Simulated track position 0 is line chainage ``LINE_START_CHAINAGE_M + RUN_OFFSET_M``."""

_CRS = CRS.from_proj4(
    f"+proj=tmerc +lat_0={LAT0} +lon_0={LON0} +k=1 +x_0=0 +y_0=0 +ellps=WGS84 +units=m"
)
_TO_LL = Transformer.from_crs(_CRS, CRS.from_epsg(4326), always_xy=True)


def plan_xy(
    s: NDArray[np.float64],
    straight_m: float = 300.0,
    radius_m: float = 1200.0,
    arc_m: float = 600.0,
    heading_deg: float = 30.0,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Plane position (m) at arc length ``s`` (m) along straight - bend - straight."""
    s = np.asarray(s, dtype=np.float64)
    h0 = np.radians(heading_deg)
    # heading along the line: constant, then turning at 1/R, then constant again
    a = np.clip(s - straight_m, 0.0, arc_m) / radius_m
    x = np.where(
        s <= straight_m,
        s * np.cos(h0),
        straight_m * np.cos(h0) + radius_m * (np.sin(h0 + a) - np.sin(h0)),
    )
    y = np.where(
        s <= straight_m,
        s * np.sin(h0),
        straight_m * np.sin(h0) - radius_m * (np.cos(h0 + a) - np.cos(h0)),
    )
    beyond = np.maximum(s - straight_m - arc_m, 0.0)
    h1 = h0 + arc_m / radius_m
    return x + beyond * np.cos(h1), y + beyond * np.sin(h1)


def to_lonlat(
    x: NDArray[np.float64], y: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """WGS84 degrees of plane points (m)."""
    lon, lat = _TO_LL.transform(x, y)
    return np.asarray(lon), np.asarray(lat)


def centerline_geojson(
    length_m: float = 1400.0, step_m: float = 5.0, start_chainage_m: float = LINE_START_CHAINAGE_M
) -> dict[str, Any]:
    """A GeoJSON Feature: the bent line, vertex every ``step_m``, chainage from its start."""
    s = np.arange(0.0, length_m + 1e-9, step_m)
    lon, lat = to_lonlat(*plan_xy(s))
    return {
        "type": "Feature",
        "properties": {"start_chainage_m": start_chainage_m, "name": "synthetic bend"},
        "geometry": {
            "type": "LineString",
            "coordinates": [[round(a, 9), round(b, 9)] for a, b in zip(lon, lat, strict=True)],
        },
    }


def gnss_fixes(
    line_chainage_m: NDArray[np.float64],
    time_s: NDArray[np.float64],
    *,
    rate_hz: float = 10.0,
    white_m: float = 1.5,
    bias_m: float = 1.0,
    bias_tau_s: float = 30.0,
    lateral_m: float = 0.0,
    seed: int = 0,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Latitude and longitude (degrees, NaN between fixes) of a body at ``line_chainage_m``.

    ``white_m`` and ``bias_m`` are per-axis standard deviations (m); the bias is an OU process
    with correlation time ``bias_tau_s``; ``lateral_m`` shifts every fix sideways (a parallel
    track, or a line 50 m away).
    """
    rng = np.random.default_rng(seed)
    s = line_chainage_m - LINE_START_CHAINAGE_M
    x, y = plan_xy(s)
    if lateral_m:
        dx, dy = np.gradient(x), np.gradient(y)
        norm = np.hypot(dx, dy)
        x, y = x - lateral_m * dy / norm, y + lateral_m * dx / norm
    step = max(1, int(round(1.0 / (rate_hz * float(time_s[1] - time_s[0])))))
    idx = np.arange(0, time_s.size, step)
    dt = step * float(time_s[1] - time_s[0])
    phi = np.exp(-dt / bias_tau_s)
    bias = np.zeros((idx.size, 2))
    bias[0] = rng.normal(0.0, bias_m, 2)
    kick = rng.normal(0.0, bias_m * np.sqrt(1 - phi * phi), (idx.size, 2))
    for i in range(1, idx.size):
        bias[i] = phi * bias[i - 1] + kick[i]
    noise = rng.normal(0.0, white_m, (idx.size, 2)) + bias
    lon_f, lat_f = to_lonlat(x[idx] + noise[:, 0], y[idx] + noise[:, 1])
    lat = np.full(time_s.size, np.nan)
    lon = np.full(time_s.size, np.nan)
    lat[idx], lon[idx] = lat_f, lon_f
    return lat, lon


def with_fixes(
    log: RunLog, lat: NDArray[np.float64], lon: NDArray[np.float64], speed_factor: float = 1.0
) -> RunLog:
    """The log with fixes added and its speed scaled (an odometer off by ``speed_factor``)."""
    assert log.speed_mps is not None
    return dataclasses.replace(
        log, lat_deg=lat, lon_deg=lon, speed_mps=log.speed_mps * speed_factor
    )


def csv_with_fixes(log: RunLog, digits: int = 8) -> bytes:
    """A CSV of the log with ``lat``/``lon`` columns, empty between fixes."""
    buf = io.StringIO()
    write_run_csv(dataclasses.replace(log, lat_deg=None, lon_deg=None), buf, digits=digits)
    lines = buf.getvalue().splitlines()
    assert log.lat_deg is not None and log.lon_deg is not None
    out = [lines[0] + ",lat,lon"]
    k = 0
    for line in lines[1:]:
        if not line or line.startswith("#"):
            out.append(line)
            continue
        la, lo = log.lat_deg[k], log.lon_deg[k]
        out.append(line + (f",{la:.9f},{lo:.9f}" if np.isfinite(la) else ",,"))
        k += 1
    return ("\n".join(out) + "\n").encode()
