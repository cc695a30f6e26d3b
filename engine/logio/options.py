"""How to read a logger's CSV: :class:`CsvOptions`, the one list of column/unit options."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import asdict, dataclass, fields
from typing import Any

from ..errors import ParameterError
from .roles import (
    _GRAVITY_MODES,
    _OPTION_UNITS,
    _ROLES,
    ROLES,
    _unit_key,
)


@dataclass(frozen=True)
class CsvOptions:
    """How to read a logger's CSV; every field left at ``None`` is recognised automatically.

    Parameters
    ----------
    time_column, accel_column, pitch_rate_column, speed_column, chainage_column : str, optional
        Header name of the column holding the sample time, the vertical body acceleration, the
        body pitch rate, the vehicle speed and the chainage (odometer). Matched exactly, else
        ignoring case and surrounding spaces. Explicit names always win over recognition.
    wheel_load_column : str, optional
        Header name of a load-weigh system's static wheel load (optional: a log without one
        uses the declared or registered load).
    time_unit : {'s', 'ms', 'epoch_s'}, optional
        Unit of the time column. ``'epoch_s'`` (Unix seconds) is shifted to start at 0.
        Default: from the column name's suffix (``_s``, ``_ms``), else epoch seconds when the
        values exceed 1e8 (epoch milliseconds above 1e11), else seconds.
    accel_unit : {'m/s2', 'g'}, optional
        Unit of the acceleration (also ``m/s^2``, ``m/s²``, ``mps2``). Default: from the name
        (``_g``, ``_mps2``, ``_ms2``), else g when the mean is about 1, else m/s².
    pitch_rate_unit : {'rad/s', 'deg/s'}, optional
        Unit of the pitch rate (also ``radps``, ``dps``). Default: from the name (``_radps``,
        ``_rads``, ``_dps``, ``_degps``), else rad/s.
    speed_unit : {'m/s', 'km/h'}, optional
        Unit of the speed (also ``mps``, ``kmh``, ``kph``). Default: from the name (``_mps``,
        ``_kmh``, ``_kph``), else m/s.
    chainage_unit : {'m', 'km'}, optional
        Unit of the chainage. Default: from the name (``_m``, ``_km``, a column called ``km``),
        else m.
    wheel_load_unit : {'N', 'kN', 't'}, optional
        Unit of the static wheel load (``'t'``: tonne-force, 9.81 kN). Default: from the name
        (``_n``, ``_kn``, ``_t``), else kN.
    lat_column, lon_column : str, optional
        Header name of the GNSS latitude and longitude columns (WGS84). Optional roles: a log
        without them is placed by its start chainage. Their cells may be empty between fixes.
    lat_unit, lon_unit : {'deg'}, optional
        Unit of the latitude and longitude: decimal degrees (the only one read).
    gravity : {'auto', 'included', 'removed'}
        Whether the acceleration includes gravity (reads about +1 g at rest). ``'included'``
        subtracts 9.81 m/s²; ``'auto'`` decides from the mean acceleration.

    Raises
    ------
    ParameterError
        An option has a value outside the allowed ones (the message lists them), or two
        options name the same column.
    """

    time_column: str | None = None
    accel_column: str | None = None
    pitch_rate_column: str | None = None
    speed_column: str | None = None
    chainage_column: str | None = None
    wheel_load_column: str | None = None
    lat_column: str | None = None
    lon_column: str | None = None
    time_unit: str | None = None
    accel_unit: str | None = None
    pitch_rate_unit: str | None = None
    speed_unit: str | None = None
    chainage_unit: str | None = None
    wheel_load_unit: str | None = None
    lat_unit: str | None = None
    lon_unit: str | None = None
    gravity: str = "auto"

    def __post_init__(self) -> None:
        seen: dict[str, str] = {}
        for role in ROLES:
            opt = f"{role}_column"
            value = getattr(self, opt)
            if value is not None and not isinstance(value, str):
                raise ParameterError(
                    f"{opt} must be a column name (text), got {value!r}", field=opt
                )
            value = value.strip() if value is not None else None
            value = value or None
            object.__setattr__(self, opt, value)
            if value is not None:
                if value in seen:
                    raise ParameterError(
                        f"{seen[value]} and {opt} both name the column {value!r}: "
                        "each column can have one meaning only",
                        field=opt,
                    )
                seen[value] = opt
        for role in ROLES:
            opt = f"{role}_unit"
            object.__setattr__(self, opt, _canonical_option_unit(role, getattr(self, opt)))
        g = self.gravity
        g = "auto" if g is None else g
        if not isinstance(g, str) or g.strip().lower() not in _GRAVITY_MODES:
            raise ParameterError(
                f"gravity must be one of 'auto', 'included', 'removed', got {self.gravity!r}",
                field="gravity",
            )
        object.__setattr__(self, "gravity", g.strip().lower())

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> CsvOptions:
        """Build from a mapping of option names (e.g. form fields); ``None``/empty = default.

        Raises
        ------
        ParameterError
            On an unknown key (the message lists the known ones) or a bad value.
        """
        known = [f.name for f in fields(cls)]
        unknown = sorted(set(d) - set(known))
        if unknown:
            raise ParameterError(
                f"unknown CSV option(s) {', '.join(unknown)}; known options: {', '.join(known)}",
                field=unknown[0],
            )
        kw = {k: v for k, v in d.items() if v is not None and v != ""}
        return cls(**kw)

    def to_dict(self) -> dict[str, str | None]:
        """The options as a plain dict (canonical unit spellings)."""
        return asdict(self)


def _canonical_option_unit(role: str, value: object) -> str | None:
    if value is None:
        return None
    opt = f"{role}_unit"
    allowed = _OPTION_UNITS[role]
    listed = ", ".join(repr(u) for u in allowed)
    if not isinstance(value, str):
        raise ParameterError(f"{opt} must be one of {listed}, got {value!r}", field=opt)
    if not value.strip():
        return None
    key = _unit_key(value)
    if role == "time" and key in ("epochs", "epoch"):
        return "epoch_s"
    unit = _ROLES[role].units.get(key)
    if unit is None or unit not in allowed:
        raise ParameterError(
            f"{opt} {value!r} is not supported: use one of {listed} "
            "(or leave it empty to recognise the unit from the column name)",
            field=opt,
        )
    return unit
