"""What each column of a run log means (its role), the names it goes by, and its units."""

from __future__ import annotations

import math
import re
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field

from ..vehicle import GRAVITY

G_UNIT_MPS2 = GRAVITY
"""Value of 1 g when converting from the unit g, m/s². The model's own gravity is used (not the
standard 9.80665) so that a logger at rest reading exactly 1 g gives exactly zero once gravity
is removed."""

SPARSE_ROLES = ("lat", "lon")
"""Roles whose column may have empty cells: GNSS fixes come at 1-10 Hz in a log sampled at
hundreds of Hz, so most rows have no position (an empty cell reads as NaN, "no fix")."""


@dataclass(frozen=True)
class _Role:
    key: str
    label: str
    canonical: str
    aliases: frozenset[str]
    units: Mapping[str, str]  # compact unit spelling -> canonical unit
    unsupported: frozenset[str]  # compact unit spellings we recognise but do not convert
    factors: Mapping[str, float]  # canonical unit -> factor to SI
    examples: str  # for error messages: names that are recognised
    alias_units: Mapping[str, str] = field(default_factory=dict)  # names that imply a unit


def _words(text: str) -> list[str]:
    return text.split()


def _units(table: Mapping[str, Iterable[str]]) -> dict[str, str]:
    return {spelling: unit for unit, spellings in table.items() for spelling in spellings}


def _wgs84_role(key: str, label: str, aliases: str, examples: str) -> _Role:
    """A GNSS coordinate's role: WGS84 degrees, whatever the coordinate."""
    return _Role(
        key=key,
        label=label,
        canonical=f"{key}_deg",
        aliases=frozenset(_words(aliases)),
        units=_units({"deg": _words("deg degs degree degrees")}),
        unsupported=frozenset(_words("rad rads radian radians mdeg udeg e7 deg7 semicircles")),
        factors={"deg": 1.0},
        examples=examples,
    )


def _by_key(*roles: _Role) -> dict[str, _Role]:
    return {r.key: r for r in roles}


_ROLES = _by_key(
    _Role(
        key="time",
        label="time",
        canonical="time_s",
        aliases=frozenset(
            _words(
                "time t timestamp time_stamp ts epoch unix_time unixtime epoch_time elapsed "
                "elapsed_time sample_time"
            )
        ),
        units=_units(
            {
                "s": _words("s sec secs second seconds"),
                "ms": _words("ms msec msecs millis millisecond milliseconds"),
                "epoch_s": _words("epoch epochs unix unixs epochsec epochseconds unixtime"),
            }
        ),
        unsupported=frozenset(_words("us usec micros ns nsec min mins h hr")),
        factors={"s": 1.0, "ms": 1e-3, "epoch_s": 1.0},
        examples="time_s, time_ms, timestamp, time, t",
        alias_units={"epoch": "epoch_s", "unix_time": "epoch_s", "unixtime": "epoch_s"},
    ),
    _Role(
        key="accel",
        label="vertical acceleration",
        canonical="accel_z_mps2",
        aliases=frozenset(
            _words(
                "accel_z acc_z az a_z accz accelz acceleration_z accel acc acceleration "
                "vertical_accel vertical_acceleration accel_vertical acc_vertical acc_vert "
                "accel_vert lin_acc_z linear_acceleration_z z_accel z_acc"
            )
        ),
        units=_units({"m/s2": _words("ms2 mps2 mss mpss msec2 mpersec2"), "g": ["g", "gs"]}),
        unsupported=frozenset(_words("mg millig mms2 cms2 gal ftps2 fts2 counts lsb")),
        factors={"m/s2": 1.0, "g": G_UNIT_MPS2},
        examples="accel_z_mps2, az_g, acc_z_ms2, accel_z, acc_z, az",
    ),
    _Role(
        key="pitch_rate",
        label="pitch rate",
        canonical="pitch_rate_radps",
        aliases=frozenset(
            _words(
                "pitch_rate pitchrate pitch_velocity gyro_y gyr_y gyroy gy wy w_y omega_y rate_y "
                "angular_rate_y ang_rate_y angular_velocity_y ang_vel_y gyro"
            )
        ),
        units=_units(
            {
                "rad/s": _words("rads radps radsec radpersec radpers"),
                "deg/s": _words("degs dps degps degsec degpersec degpers"),
            }
        ),
        unsupported=frozenset(_words("rpm mrads mdps counts lsb")),
        factors={"rad/s": 1.0, "deg/s": math.pi / 180.0},
        examples="pitch_rate_radps, gyro_y_dps, gyro_y_rads, gyro_y, pitch_rate, gy",
    ),
    _Role(
        key="speed",
        label="speed",
        canonical="speed_mps",
        aliases=frozenset(
            _words("speed v vel velocity spd ground_speed gps_speed train_speed vehicle_speed")
        ),
        units=_units(
            {
                "m/s": _words("ms mps mpersec msec"),
                "km/h": _words("kmh kph kmph kmhr kmperh kmperhour"),
            }
        ),
        unsupported=frozenset(_words("mph kn kt knots kts fts fps")),
        factors={"m/s": 1.0, "km/h": 1.0 / 3.6},
        examples="speed_mps, speed_kmh, speed_kph, speed, v",
    ),
    _Role(
        key="chainage",
        label="chainage",
        canonical="chainage_m",
        aliases=frozenset(
            _words(
                "chainage km position pos odometer odo distance dist mileage kilometrage "
                "track_position location"
            )
        ),
        units=_units({"m": _words("m metre meter metres meters"), "km": ["km"]}),
        unsupported=frozenset(_words("mi mile miles ft feet yd")),
        factors={"m": 1.0, "km": 1000.0},
        examples="chainage_m, odometer_m, position, chainage, km",
        alias_units={"km": "km", "kilometrage": "km"},
    ),
    # A load-weigh system (air-spring pressure or strain gauges) measures the static load the
    # vehicle carries today: the wheel force the inversion cannot know from the log alone.
    _Role(
        key="wheel_load",
        label="static wheel load",
        canonical="wheel_load_n",
        aliases=frozenset(
            _words(
                "wheel_load static_wheel_load wheelload static_load load_weigh loadweigh "
                "load_weigh_wheel lw_wheel_load weighed_wheel_load wheel_load_static"
            )
        ),
        units=_units({"N": ["n"], "kN": ["kn"], "t": _words("t tf tonne tonnes")}),
        unsupported=frozenset(_words("kg lb lbs lbf kip kips bar psi")),
        factors={"N": 1.0, "kN": 1e3, "t": 1e3 * GRAVITY},
        examples="wheel_load_kn, static_wheel_load_n, load_weigh_kn",
    ),
    _wgs84_role(
        "lat",
        "latitude",
        "lat latitude gps_lat gnss_lat lat_wgs84 latitude_wgs84 gps_latitude gnss_latitude "
        "pos_lat position_lat",
        examples="lat, latitude, gps_lat, gnss_lat, lat_deg",
    ),
    _wgs84_role(
        "lon",
        "longitude",
        "lon lng long longitude gps_lon gps_lng gnss_lon gnss_lng lon_wgs84 longitude_wgs84 "
        "gps_longitude gnss_longitude pos_lon position_lon",
        examples="lon, lng, longitude, gps_lon, gnss_lon, lon_deg",
    ),
)
ROLES = tuple(_ROLES)
"""Every column role, in display order. ``wheel_load`` (a load-weigh system's static wheel load)
and ``lat``/``lon`` (GNSS fixes) are optional; the others are needed (speed or chainage, at
least one)."""


def role_aliases(role: str) -> frozenset[str]:
    """The header names (lower snake case) a column of ``role`` is recognised by, including
    its canonical name (``'lat'`` -> ``{'lat', 'latitude', ..., 'lat_deg'}``)."""
    r = _ROLES[role]
    return r.aliases | {r.canonical}


_OPTION_UNITS = {role: tuple(r.factors) for role, r in _ROLES.items()}
_GRAVITY_MODES = ("auto", "included", "removed")
OPTION_UNITS = _OPTION_UNITS
"""Role -> the units a column of that role can be read in (the ``<role>_unit`` options)."""
GRAVITY_MODES = _GRAVITY_MODES
"""Values of the ``gravity`` option."""
UNIT_LABELS = {
    "m/s2": "m/s²", "g": "g (9.81 m/s²)", "epoch_s": "epoch seconds", "t": "t (tonne-force)",
    "deg": "degrees",
}  # fmt: skip
"""How a unit is written for people, where that differs from its option value."""
ROLE_LABELS = {role: r.label for role, r in _ROLES.items()}
"""Role -> its name in words (``'pitch_rate'`` -> ``'pitch rate'``)."""
OPTIONAL_ROLES = ("wheel_load", "lat", "lon")
"""Roles a log may lack without anything else standing in for them."""
_UNIT_LABEL = {"m/s2": "m/s²", "epoch_s": "epoch s"}


def _unit_key(text: str) -> str:
    """Compact spelling of a unit: lower case, no separators (``'m/s^2'`` -> ``'ms2'``)."""
    t = text.lower().replace("²", "2").replace("°", "deg").replace("µ", "u")
    return re.sub(r"[^a-z0-9]", "", t)


def _label(unit: str) -> str:
    return _UNIT_LABEL.get(unit, unit)
