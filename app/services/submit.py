"""Accepting a run: moved to :mod:`app.services.run_lifecycle` (intake, accept, store).

The names stay importable from here for the modules that import them from this path.
"""

from __future__ import annotations

from .run_lifecycle.accept import submit
from .run_lifecycle.intake import (
    DEFAULT_VEHICLE,
    Submission,
    clean_filename,
    ignored_options,
    resolve_track,
    resolve_vehicle,
    vehicle_from_preset,
)

__all__ = [
    "DEFAULT_VEHICLE", "Submission", "clean_filename", "ignored_options", "resolve_track",
    "resolve_vehicle", "submit", "vehicle_from_preset",
]  # fmt: skip
