"""Column recognition: which header name plays which role, and the unit its name implies."""

from __future__ import annotations

import re
from collections.abc import Iterator
from dataclasses import dataclass

from ..errors import LogFormatError
from .options import CsvOptions
from .roles import (
    _OPTION_UNITS,
    _ROLES,
    ROLES,
    _label,
    _Role,
    _unit_key,
)

_BRACKET_UNIT = re.compile(r"[\(\[\{]([^\)\]\}]*)[\)\]\}]\s*$")


def _split_name(name: str) -> tuple[str, str | None]:
    """Snake-case base of a column name and the unit written in brackets, if any."""
    unit = None
    m = _BRACKET_UNIT.search(name)
    if m:
        unit, name = m.group(1), name[: m.start()]
    s = re.sub(r"(?<=[a-z0-9])(?=[A-Z])", "_", name.strip())  # camelCase -> camel_Case
    s = s.lower().replace("²", "2").replace("°", "deg")
    return re.sub(r"[^a-z0-9]+", "_", s).strip("_"), unit


def _unit_suffixes(base: str) -> Iterator[tuple[str, str, str]]:
    """The splits of a snake-case name into a stem and a unit suffix of its last one to three
    tokens, shortest suffix first, always leaving a stem: (stem, unit key, suffix as written)."""
    tokens = base.split("_")
    for k in (1, 2, 3):
        if len(tokens) <= k:
            break
        yield "_".join(tokens[:-k]), "".join(tokens[-k:]), "_".join(tokens[-k:])


@dataclass(frozen=True)
class _Match:
    unit: str | None  # canonical unit the name implies, None when it says nothing
    unsupported: str | None = None  # a unit we recognise but cannot convert


def _match(name: str, role: _Role) -> _Match | None:
    """Whether a column name fits a role, and the unit its name implies."""
    base, bracket = _split_name(name)
    if bracket is not None:
        if base not in role.aliases and base != role.canonical:
            return None
        key = _unit_key(bracket)
        if not key:
            return _Match(role.alias_units.get(base))
        if key in role.units:
            return _Match(role.units[key])
        return _Match(None, unsupported=bracket.strip())
    if base in role.aliases:
        return _Match(role.alias_units.get(base))
    for stem, key, written in _unit_suffixes(base):
        if stem in role.aliases:
            if key in role.units:
                return _Match(role.units[key])
            if key in role.unsupported:
                return _Match(None, unsupported=written)
    return None


def _unit_from_name(name: str, role: _Role) -> str | None:
    """Unit implied by any column name's suffix or bracket (for explicitly chosen columns)."""
    base, bracket = _split_name(name)
    if bracket is not None:
        return role.units.get(_unit_key(bracket))
    if base in role.alias_units:
        return role.alias_units[base]
    for _stem, key, _written in _unit_suffixes(base):
        if key in role.units:
            return role.units[key]
    return None


def _find_column(names: list[str], wanted: str) -> int | None:
    if wanted in names:
        return names.index(wanted)
    folded = [i for i, n in enumerate(names) if n.strip().casefold() == wanted.strip().casefold()]
    return folded[0] if len(folded) == 1 else None


@dataclass
class _Mapping:
    index: dict[str, int | None]
    name_unit: dict[str, str | None]
    problems: list[LogFormatError]


def _columns_found(names: list[str]) -> str:
    return ", ".join(repr(n) for n in names)


def _map_columns(names: list[str], options: CsvOptions, header_line: int) -> _Mapping:
    """Assign columns to roles; problems are collected, not raised (the preview shows them)."""
    problems: list[LogFormatError] = []
    index: dict[str, int | None] = dict.fromkeys(ROLES)
    name_unit: dict[str, str | None] = dict.fromkeys(ROLES)

    seen: dict[str, int] = {}
    for j, n in enumerate(names):
        if n in seen:
            problems.append(
                LogFormatError(
                    f"column {n!r} appears twice in the header (line {header_line}, columns "
                    f"{seen[n] + 1} and {j + 1}): every column needs its own name",
                    column=n,
                    row=header_line,
                )
            )
        else:
            seen[n] = j

    taken: set[int] = set()
    for role in ROLES:
        wanted = getattr(options, f"{role}_column")
        if wanted is None:
            continue
        found = _find_column(names, wanted)
        if found is None:
            problems.append(
                LogFormatError(
                    f"{role}_column {wanted!r} is not a column of the file; "
                    f"columns found: {_columns_found(names)}",
                    column=wanted,
                    row=header_line,
                )
            )
            continue
        index[role] = found
        name_unit[role] = _unit_from_name(names[found], _ROLES[role])
        taken.add(found)

    near_misses: dict[str, list[str]] = {r: [] for r in ROLES}
    for role in ROLES:
        if getattr(options, f"{role}_column") is not None:
            continue
        spec = _ROLES[role]
        cands: list[tuple[int, _Match]] = []
        for j, n in enumerate(names):
            if j in taken:
                continue
            m = _match(n, spec)
            if m is None:
                continue
            if m.unsupported is not None:
                near_misses[role].append(
                    f"column {n!r} looks like the {spec.label} but its unit {m.unsupported!r} "
                    f"is not supported (use {' or '.join(_label(u) for u in _OPTION_UNITS[role])})"
                )
                continue
            cands.append((j, m))
        if len(cands) > 1:
            listed = " and ".join(repr(names[j]) for j, _ in cands)
            problems.append(
                LogFormatError(
                    f"{len(cands)} columns could be the {spec.label}: {listed}; "
                    f"set {role}_column to the one to use",
                    column=names[cands[0][0]],
                    row=header_line,
                )
            )
        elif cands:
            j, m = cands[0]
            index[role], name_unit[role] = j, m.unit

    def missing(roles: tuple[str, ...]) -> None:
        labels = " or ".join(_ROLES[r].label for r in roles)
        expected = "; ".join(f"{_ROLES[r].label}: {_ROLES[r].examples}" for r in roles)
        opts = " or ".join(f"{r}_column" for r in roles)
        extra = [m + "." for r in roles for m in near_misses[r]]
        if all(re.fullmatch(r"[+-]?[\d.eE+-]+", n) for n in names):
            extra.append(
                "The first line holds numbers: the file needs a header line naming columns."
            )
        problems.append(
            LogFormatError(
                " ".join(
                    [
                        f"no {labels} column: columns found (line {header_line}): "
                        f"{_columns_found(names)}; expected names such as {expected}, "
                        f"or set {opts}.",
                        *extra,
                    ]
                ),
                column=_ROLES[roles[0]].canonical,
                row=header_line,
            )
        )

    for role in ("time", "accel", "pitch_rate"):
        if index[role] is None and getattr(options, f"{role}_column") is None:
            missing((role,))
    lat, lon = index["lat"], index["lon"]
    if (lat is None) != (lon is None):
        have, lack = ("lat", "lon") if lon is None else ("lon", "lat")
        problems.append(
            LogFormatError(
                f"column {names[index[have] or 0]!r} is the {_ROLES[have].label} but no column is "
                f"the {_ROLES[lack].label}: positions need both (expected names such as "
                f"{_ROLES[lack].examples}, or set {lack}_column)",
                column=names[index[have] or 0],
                row=header_line,
            )
        )
    if (
        index["speed"] is None
        and index["chainage"] is None
        and options.speed_column is None
        and options.chainage_column is None
    ):
        missing(("speed", "chainage"))
    return _Mapping(index=index, name_unit=name_unit, problems=problems)
