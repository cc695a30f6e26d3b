"""Why a run cannot be placed on a centerline, or a centerline cannot be read.

Plain :class:`ValueError` subclasses (through :class:`engine.errors.EngineError`), so callers
that know only the standard library can catch them; the service maps them to its own errors.
"""

from __future__ import annotations

from ..errors import EngineError


class CenterlineError(EngineError):
    """A centerline is not usable: too few points, degrees out of range, lat/lon swapped,
    a self-intersecting line, chainage that does not grow.

    Attributes
    ----------
    field : str or None
        What is wrong (``'coordinates'``, ``'chainage_m'``, ``'start_chainage_m'``, ...).
    row : int or None
        The 1-based vertex (GeoJSON) or file line (CSV) at fault, when there is one.
    """

    def __init__(self, message: str, *, field: str | None = None, row: int | None = None):
        super().__init__(message)
        self.field = field
        self.row = row


class PositioningError(EngineError):
    """A run's fixes cannot place it on the centerline."""


class NoFixes(PositioningError):
    """The run has no usable position fixes (latitude/longitude)."""


class TooFewFixes(PositioningError):
    """Too few fixes near the line to fit start, direction and scale."""


class FixesOffLine(PositioningError):
    """The fixes lie too far from the centerline (another line, or a wrong centerline).

    Attributes
    ----------
    median_offset_m : float
        Median distance of the fixes from the centerline, m.
    """

    def __init__(self, message: str, *, median_offset_m: float):
        super().__init__(message)
        self.median_offset_m = median_offset_m


class FixesBesideLine(FixesOffLine):
    """The fixes follow the line, but steadily to one side of it: a neighbouring track.

    Attributes
    ----------
    median_offset_m : float
        Size of the steady offset, m.
    lateral_offset_m : float
        The median signed lateral offset, m (positive: left of the line looking towards
        increasing chainage).
    """

    def __init__(self, message: str, *, median_offset_m: float, lateral_offset_m: float):
        super().__init__(message, median_offset_m=median_offset_m)
        self.lateral_offset_m = lateral_offset_m


class FixesDoNotFollowLine(PositioningError):
    """The fixes are near the line but do not move along it as the odometer does (another
    line crossing or running close, a wrong track, or a broken speed signal)."""
