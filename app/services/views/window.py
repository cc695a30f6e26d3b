"""A chainage window: the one rule every windowed read (profiles, maps, exports) follows."""

from __future__ import annotations

from dataclasses import dataclass

from app.services.errors import Invalid


@dataclass(frozen=True)
class Window:
    """An inclusive window of aligned chainage, m; an end left None is open.

    One rule for every endpoint: ``to_m`` may not be before ``from_m``; ``from_m == to_m``
    is a window of one point (the grid point there, if any), not an error, because every
    windowed read is inclusive at both ends.
    """

    from_m: float | None = None
    to_m: float | None = None

    def __post_init__(self) -> None:
        if self.from_m is not None and self.to_m is not None and self.to_m < self.from_m:
            raise Invalid(f"to_m ({self.to_m} m) is before from_m ({self.from_m} m)", field="to_m")

    @property
    def span_m(self) -> float | None:
        """Width of a closed window, m (None when an end is open)."""
        if self.from_m is None or self.to_m is None:
            return None
        return self.to_m - self.from_m

    def stored(self, offset_m: float) -> tuple[float | None, float | None]:
        """The window on a run's stored chainage (aligned chainage minus its offset), m."""
        return (
            None if self.from_m is None else self.from_m - offset_m,
            None if self.to_m is None else self.to_m - offset_m,
        )
