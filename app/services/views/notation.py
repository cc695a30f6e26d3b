"""How a chainage is written for a person: the railway notation ``km+m`` (``12+645.0``).

The API answers in metres; every page, report and message a person reads writes a chainage
with :func:`km_m` (the dashboard's twin is ``fmtKm`` in ``static/js/dom.js``).
"""

from __future__ import annotations

import math


def km_m(chainage_m: float | None, digits: int = 1) -> str:
    """``12645.04`` m -> ``12+645.0``; ``-12.5`` -> ``-0+012.5``; None or NaN -> ``—``.

    Parameters
    ----------
    chainage_m : float or None
        Chainage, m.
    digits : int
        Decimals of the metres.
    """
    if chainage_m is None or not math.isfinite(chainage_m):
        return "—"
    sign = "-" if chainage_m < 0 else ""
    scaled = round(abs(chainage_m), digits)
    km = int(scaled // 1000)
    m = scaled - 1000 * km
    width = 3 + (digits + 1 if digits > 0 else 0)
    return f"{sign}{km}+{m:0{width}.{digits}f}"


def km_m_range(start_m: float | None, end_m: float | None, digits: int = 1) -> str:
    """``0+120.0–0+126.0``: a stretch from one chainage to another."""
    return f"{km_m(start_m, digits)}–{km_m(end_m, digits)}"
