"""A line's centerline: WGS84 vertices with their chainage, and linear referencing onto it.

Geometry is not home-made: pyproj gives the geodesic length of each segment (the chainage of a
GeoJSON line grows with it) and a local transverse Mercator projection centred on the line
(scale error below 1e-4 within 100 km of the centre, so metres in the plane are metres on the
ground to the GNSS's accuracy); shapely finds each fix's nearest segment (an STR-tree query,
vectorised over all fixes) and checks that the line does not cross itself.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import shapely
from numpy.typing import ArrayLike, NDArray
from pyproj import CRS, Geod, Transformer

from .errors import CenterlineError

MAX_VERTICES = 200_000
"""Most vertices a centerline may have (a 1 000 km line at 5 m spacing)."""

MAX_EXTENT_M = 500_000.0
"""Farthest a vertex may be from the line's centre, m: the local projection's scale error
stays below 0.3 % there (a line longer than ~1 000 km should be split)."""

_GEOD = Geod(ellps="WGS84")


@dataclass(frozen=True)
class Located:
    """Fixes referenced to a centerline.

    Attributes
    ----------
    chainage_m : ndarray
        Chainage of the nearest point of the line, m (NaN where the fix was NaN).
    offset_m : ndarray
        Distance from the line (lateral offset), m.
    lateral_m : ndarray
        Signed lateral offset, m: ``offset_m`` positive left of the line, negative right of
        it, looking towards increasing chainage.
    """

    chainage_m: NDArray[np.float64]
    offset_m: NDArray[np.float64]
    lateral_m: NDArray[np.float64]


@dataclass(frozen=True)
class Centerline:
    """A track's centerline: vertices in WGS84 degrees and the chainage of each, m.

    Parameters
    ----------
    lon_deg, lat_deg : array_like, shape (n,)
        Longitude and latitude of each vertex, degrees (WGS84), ``n >= 2``.
    chainage_m : array_like, shape (n,)
        Chainage of each vertex, m, strictly increasing along the line. Between vertices the
        chainage is interpolated linearly along the line.

    Raises
    ------
    CenterlineError
        Fewer than two distinct points, degrees out of range (naming a lat/lon swap when
        swapping would fix it), a line that crosses itself, chainage not strictly increasing,
        non-finite values, more than :data:`MAX_VERTICES` vertices or a line wider than
        :data:`MAX_EXTENT_M` from its centre.
    """

    lon_deg: NDArray[np.float64]
    lat_deg: NDArray[np.float64]
    chainage_m: NDArray[np.float64]
    _to_plane: Transformer = field(init=False, repr=False, compare=False)
    _xy: NDArray[np.float64] = field(init=False, repr=False, compare=False)
    _along: NDArray[np.float64] = field(init=False, repr=False, compare=False)
    _seg_index: NDArray[np.int64] = field(init=False, repr=False, compare=False)
    _tree: shapely.STRtree = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        lon, lat, ch = (
            np.array(a, dtype=np.float64, copy=True).ravel()
            for a in (self.lon_deg, self.lat_deg, self.chainage_m)
        )
        _check_vertices(lon, lat, ch)
        for name, a in (("lon_deg", lon), ("lat_deg", lat), ("chainage_m", ch)):
            a.setflags(write=False)
            object.__setattr__(self, name, a)
        lat0, lon0 = float(np.mean(lat)), _mean_lon(lon)
        crs = CRS.from_proj4(
            f"+proj=tmerc +lat_0={lat0:.9f} +lon_0={lon0:.9f} +k=1 +x_0=0 +y_0=0 "
            "+ellps=WGS84 +units=m +no_defs"
        )
        to_plane = Transformer.from_crs(CRS.from_epsg(4326), crs, always_xy=True)
        x, y = to_plane.transform(lon, lat)
        xy = np.column_stack([x, y])
        far = np.hypot(x, y)
        if float(far.max()) > MAX_EXTENT_M:
            i = int(np.argmax(far))
            raise CenterlineError(
                f"vertex {i + 1} is {far[i] / 1000:.0f} km from the line's centre: a centerline "
                f"may extend at most {MAX_EXTENT_M / 1000:.0f} km from its centre (split longer "
                "lines into several tracks)",
                field="coordinates",
                row=i + 1,
            )
        seg = np.hypot(np.diff(x), np.diff(y))
        along = np.concatenate([[0.0], np.cumsum(seg)])
        if not shapely.is_simple(shapely.linestrings(xy)):
            raise CenterlineError(
                "the centerline crosses itself (it is not a simple line): a chainage would "
                "belong to two places; give the line once, in order of chainage",
                field="coordinates",
            )
        keep = seg > 0  # repeated points (a chainage equation) have no segment to project on
        segments = shapely.linestrings(
            np.stack([xy[:-1][keep], xy[1:][keep]], axis=1)  # (m, 2, 2)
        )
        object.__setattr__(self, "_to_plane", to_plane)
        object.__setattr__(self, "_xy", xy)
        object.__setattr__(self, "_along", along)
        object.__setattr__(self, "_seg_index", np.flatnonzero(keep))
        object.__setattr__(self, "_tree", shapely.STRtree(segments))

    @property
    def n_vertices(self) -> int:
        """Number of vertices."""
        return int(self.lon_deg.size)

    @property
    def length_m(self) -> float:
        """Length of the line in the local projection, m."""
        return float(self._along[-1])

    @property
    def start_chainage_m(self) -> float:
        """Chainage of the first vertex, m."""
        return float(self.chainage_m[0])

    @property
    def end_chainage_m(self) -> float:
        """Chainage of the last vertex, m."""
        return float(self.chainage_m[-1])

    def to_plane(
        self, lon_deg: ArrayLike, lat_deg: ArrayLike
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Local metric coordinates (east, north) of WGS84 points, m, origin at the centre."""
        x, y = self._to_plane.transform(
            np.asarray(lon_deg, dtype=np.float64), np.asarray(lat_deg, dtype=np.float64)
        )
        return np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64)

    def plane(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The vertices in local metres (east, north), m."""
        return self._xy[:, 0].copy(), self._xy[:, 1].copy()

    def locate(self, lon_deg: ArrayLike, lat_deg: ArrayLike) -> Located:
        """Chainage of the nearest point of the line and distance from it, for each fix.

        Parameters
        ----------
        lon_deg, lat_deg : array_like, shape (k,)
            Fixes in WGS84 degrees; NaN entries give NaN results.

        Returns
        -------
        Located
            ``chainage_m`` (m), ``offset_m`` (m, >= 0) and the signed ``lateral_m`` (m).
        """
        lon = np.asarray(lon_deg, dtype=np.float64).ravel()
        lat = np.asarray(lat_deg, dtype=np.float64).ravel()
        chain = np.full(lon.shape, np.nan)
        off = np.full(lon.shape, np.nan)
        side = np.full(lon.shape, np.nan)
        ok = np.isfinite(lon) & np.isfinite(lat)
        if not ok.any():
            return Located(chain, off, side)
        px, py = self.to_plane(lon[ok], lat[ok])
        pts = shapely.points(px, py)
        idx = self._tree.query_nearest(pts, all_matches=False)
        seg = self._seg_index[idx[1]]
        order = np.argsort(idx[0])
        seg = seg[order]
        a, b = self._xy[seg], self._xy[seg + 1]
        d = b - a
        length2 = np.einsum("ij,ij->i", d, d)
        p = np.column_stack([px, py])
        u = np.clip(np.einsum("ij,ij->i", p - a, d) / length2, 0.0, 1.0)
        foot = a + u[:, None] * d
        off[ok] = np.hypot(*(p - foot).T)
        # the cross product's sign: left of the segment's direction (= increasing chainage)
        left = d[:, 0] * (p - a)[:, 1] - d[:, 1] * (p - a)[:, 0] >= 0
        side[ok] = np.where(left, off[ok], -off[ok])
        chain[ok] = self.chainage_m[seg] + u * (self.chainage_m[seg + 1] - self.chainage_m[seg])
        return Located(chain, off, side)

    def point_at(self, chainage_m: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Local metres (east, north) of the points at the given chainages (clipped to the
        line's ends), m."""
        c = np.asarray(chainage_m, dtype=np.float64)
        s = np.interp(c, self.chainage_m, self._along)
        return np.interp(s, self._along, self._xy[:, 0]), np.interp(s, self._along, self._xy[:, 1])

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready: ``lon_deg``, ``lat_deg``, ``chainage_m`` lists."""
        return {
            "lon_deg": self.lon_deg.tolist(),
            "lat_deg": self.lat_deg.tolist(),
            "chainage_m": self.chainage_m.tolist(),
        }

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> Centerline:
        """Inverse of :meth:`to_dict`."""
        return cls(d["lon_deg"], d["lat_deg"], d["chainage_m"])


def geodesic_chainage(
    lon_deg: ArrayLike, lat_deg: ArrayLike, start_chainage_m: float = 0.0
) -> NDArray[np.float64]:
    """Chainage of each vertex of a line: the start plus the geodesic (WGS84) length so far, m."""
    lon = np.asarray(lon_deg, dtype=np.float64)
    lat = np.asarray(lat_deg, dtype=np.float64)
    _check_degrees(lon, lat)
    _, _, dist = _GEOD.inv(lon[:-1], lat[:-1], lon[1:], lat[1:])
    return float(start_chainage_m) + np.concatenate([[0.0], np.cumsum(np.asarray(dist))])


def _mean_lon(lon: NDArray[np.float64]) -> float:
    # the circular mean: a line across the antimeridian is centred on it, not on 0 degrees
    r = np.radians(lon)
    return math.degrees(math.atan2(float(np.mean(np.sin(r))), float(np.mean(np.cos(r)))))


def _check_finite(values: NDArray[np.float64], name: str, kind: str, unit: str, field: str) -> None:
    """Raise for the first vertex whose ``name`` (one ``kind`` of value, in ``unit``) is not
    a finite number."""
    bad = ~np.isfinite(values)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise CenterlineError(
            f"vertex {i + 1} has {name} {values[i]}: every {kind} must be a finite number of "
            f"{unit}",
            field=field,
            row=i + 1,
        )


def _check_degrees(lon: NDArray[np.float64], lat: NDArray[np.float64]) -> None:
    for name, a in (("longitude", lon), ("latitude", lat)):
        _check_finite(a, name, "coordinate", "degrees", "coordinates")
    bad_lat = np.abs(lat) > 90.0
    bad_lon = np.abs(lon) > 180.0
    if bad_lat.any() or bad_lon.any():
        swapped = bool(np.all(np.abs(lon) <= 90.0) and np.all(np.abs(lat) <= 180.0))
        hint = (
            " The latitude and longitude look swapped: GeoJSON positions are "
            "[longitude, latitude] (x before y); CSV columns are named lat and lon."
            if swapped and bad_lat.any()
            else ""
        )
        if bad_lat.any():
            i = int(np.flatnonzero(bad_lat)[0])
            what = f"latitude {lat[i]:g} degrees, outside -90 to 90"
        else:
            i = int(np.flatnonzero(bad_lon)[0])
            what = f"longitude {lon[i]:g} degrees, outside -180 to 180"
        raise CenterlineError(
            f"vertex {i + 1} has {what} (WGS84 degrees expected).{hint}",
            field="coordinates",
            row=i + 1,
        )


def _check_vertices(
    lon: NDArray[np.float64], lat: NDArray[np.float64], ch: NDArray[np.float64]
) -> None:
    if not (lon.size == lat.size == ch.size):
        raise CenterlineError(
            f"longitude, latitude and chainage have different lengths ({lon.size}, {lat.size}, "
            f"{ch.size})",
            field="coordinates",
        )
    if lon.size > MAX_VERTICES:
        raise CenterlineError(
            f"the centerline has {lon.size} vertices, more than the {MAX_VERTICES} allowed: "
            "simplify it (a vertex every few metres is plenty)",
            field="coordinates",
        )
    _check_degrees(lon, lat)
    distinct = np.unique(np.column_stack([lon, lat]), axis=0).shape[0] if lon.size else 0
    if distinct < 2:
        raise CenterlineError(
            f"the centerline has {distinct} distinct point{'s' if distinct != 1 else ''}: "
            "a line needs at least two",
            field="coordinates",
        )
    _check_finite(ch, "chainage", "chainage", "metres", "chainage_m")
    step = np.diff(ch)
    if np.any(step <= 0):
        i = int(np.flatnonzero(step <= 0)[0])
        raise CenterlineError(
            f"chainage must grow along the line: vertex {i + 2} has {ch[i + 1]:g} m after "
            f"{ch[i]:g} m at vertex {i + 1} (give the vertices in order of chainage)",
            field="chainage_m",
            row=i + 2,
        )
