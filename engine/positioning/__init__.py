"""Positions from GNSS: a track's centerline and runs placed on it by their fixes.

- :mod:`.centerline`: :class:`Centerline` (vertices, chainage, linear referencing).
- :mod:`.formats`: reading a centerline from GeoJSON or CSV.
- :mod:`.fit`: :func:`place_run`, the robust odometer fit, and its :class:`Placement`.
- :mod:`.errors`: why a centerline or a placement is refused.
"""

from .centerline import MAX_VERTICES, Centerline, Located, geodesic_chainage
from .errors import (
    CenterlineError,
    FixesBesideLine,
    FixesDoNotFollowLine,
    FixesOffLine,
    NoFixes,
    PositioningError,
    TooFewFixes,
)
from .fit import (
    FIX_INTERVAL_S,
    LATERAL_TOLERANCE_M,
    MAX_FIXES,
    MAX_OFFSET_M,
    MIN_FIXES,
    SCALE_RANGE,
    Placement,
    place_run,
    thin_fixes,
)
from .formats import centerline_from_csv, centerline_from_geojson
from .runs import place_log

__all__ = [
    "FIX_INTERVAL_S", "LATERAL_TOLERANCE_M", "MAX_FIXES", "MAX_OFFSET_M", "MAX_VERTICES",
    "MIN_FIXES", "SCALE_RANGE", "CenterlineError", "Centerline", "FixesBesideLine",
    "FixesDoNotFollowLine", "FixesOffLine", "Located", "NoFixes", "Placement",
    "PositioningError", "TooFewFixes", "centerline_from_csv", "centerline_from_geojson",
    "geodesic_chainage", "place_log", "place_run", "thin_fixes",
]  # fmt: skip
