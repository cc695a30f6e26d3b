"""The report's stiffness section: the track's separated stiffness (% of nominal, coloured by
the loss limits) and unloaded geometry as inline SVG, its soft spots and contributing passes,
or the plain reason why geometry and stiffness cannot be separated there.

Static HTML only (no script, no external resource), like the rest of the report.
"""

from __future__ import annotations

from html import escape
from typing import Any

import numpy as np
from numpy.typing import NDArray

from app.services.track.separation_store import StiffnessWindow
from app.services.track.separation_trust import PROVISIONAL_REMEDY
from app.services.views.notation import km_m, km_m_range
from engine.decimate import minmax_indices
from engine.register import Limits

MAX_POINTS = 3000
"""Points drawn per curve (each stretch's lowest and highest kept)."""

LOSS_COLOURS = (
    ("immediate", "#7a0019"),
    ("intervention", "#D55E00"),
    ("alert", "#E69F00"),
)


def _arr(values: list[Any]) -> NDArray[np.float64]:
    return np.array([np.nan if v is None else v for v in values], dtype=np.float64)


def _colour(loss_pct: float, limits: Limits) -> str:
    for level, colour in LOSS_COLOURS:
        limit = getattr(limits, f"{level}_loss_pct")
        if limit is not None and loss_pct >= limit:
            return colour
    return "#0072B2"


def _polyline(
    x: NDArray[np.float64], y: NDArray[np.float64], sx: Any, sy: Any, colour: str, gap_m: float
) -> str:
    out = []
    seg: list[str] = []
    prev = None
    for xi, yi in zip(x.tolist(), y.tolist(), strict=True):
        if not np.isfinite(yi) or (prev is not None and xi - prev > gap_m):
            if len(seg) > 1:
                out.append(seg)
            seg = []
        if np.isfinite(yi):
            seg.append(f"{sx(xi):.1f},{sy(yi):.1f}")
        prev = xi
    if len(seg) > 1:
        out.append(seg)
    return "".join(
        f'<polyline points="{" ".join(s)}" fill="none" stroke="{colour}" stroke-width="1"/>'
        for s in out
    )


def stiffness_svg(window: StiffnessWindow, limits: Limits, width: int = 1000) -> str:
    """Stiffness (% of nominal) above, unloaded geometry (mm) below, soft spots shaded."""
    x = np.asarray(window.columns["chainage_m"], dtype=np.float64)
    k = 100.0 * _arr(window.columns["k_rel"])
    g = _arr(window.columns["geometry_mm"])
    ok = np.isfinite(k)
    ml, mr, mt, top_h, gap, bot_h, mb = 64, 16, 12, 200, 24, 110, 36
    height = mt + top_h + gap + bot_h + mb
    x0, x1 = float(x[ok][0]), float(x[ok][-1])
    if x1 - x0 < 1:
        x0, x1 = x0 - 5, x1 + 5
    pw = width - ml - mr

    def sx(v: float) -> float:
        return ml + (v - x0) / (x1 - x0) * pw

    k_lo, k_hi = min(0.0, float(np.nanmin(k))), max(120.0, float(np.nanmax(k)))
    g_fin = g[np.isfinite(g)]
    g_lo, g_hi = (float(g_fin.min()), float(g_fin.max())) if g_fin.size else (-1.0, 1.0)
    if g_hi <= g_lo:
        g_lo, g_hi = g_lo - 0.5, g_hi + 0.5

    def sk(v: float) -> float:
        return mt + top_h - (v - k_lo) / (k_hi - k_lo) * top_h

    def sg(v: float) -> float:
        return mt + top_h + gap + bot_h - (v - g_lo) / (g_hi - g_lo) * bot_h

    inside = (x >= x0) & (x <= x1)
    keep = minmax_indices(np.where(inside & ok, k, np.nan), MAX_POINTS)
    keep_g = minmax_indices(np.where(inside, g, np.nan), MAX_POINTS)
    out = [
        f'<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 {width} {height}" width="100%" '
        'role="img" aria-labelledby="stiffness-title"><title id="stiffness-title">Stiffness map: '
        "support stiffness in percent of nominal, coloured by the loss limits, and the unloaded "
        "rail geometry</title>",
        f'<rect x="{ml}" y="{mt}" width="{pw}" height="{top_h}" fill="#f8fafc" stroke="#cbd5e1"/>',
        f'<rect x="{ml}" y="{mt + top_h + gap}" width="{pw}" height="{bot_h}" fill="#f8fafc" '
        'stroke="#cbd5e1"/>',
    ]
    for s in window.spots:
        if s.end_m < x0 or s.start_m > x1:
            continue
        a, b = sx(max(s.start_m, x0)), sx(min(s.end_m, x1))
        out.append(
            f'<rect x="{a:.1f}" y="{mt}" width="{max(b - a, 1.5):.1f}" height="{top_h}" '
            f'fill="{_colour(s.loss_pct, limits)}" fill-opacity="0.18"/>'
        )
    for v in (0, 50, 100):
        if k_lo <= v <= k_hi:
            out.append(
                f'<line x1="{ml}" y1="{sk(v):.1f}" x2="{ml + pw}" y2="{sk(v):.1f}" '
                f'stroke="#94a3b8" stroke-dasharray="3 3"/><text x="{ml - 6}" y="{sk(v) + 4:.1f}" '
                f'font-size="11" text-anchor="end">{v} %</text>'
            )
    gap_m = 5 * (x1 - x0) / pw + 1.0
    out.append(_polyline(x[keep], k[keep], sx, sk, "#0072B2", gap_m))
    for i in keep.tolist():
        if np.isfinite(k[i]) and k[i] < 100.0:
            colour = _colour(100.0 - float(k[i]), limits)
            if colour != "#0072B2":
                out.append(
                    f'<circle cx="{sx(float(x[i])):.1f}" cy="{sk(float(k[i])):.1f}" r="2" '
                    f'fill="{colour}"/>'
                )
    out.append(_polyline(x[keep_g], g[keep_g], sx, sg, "#111827", gap_m))
    out.append(
        f'<text x="{ml - 6}" y="{sg(g_hi) + 4:.1f}" font-size="11" text-anchor="end">'
        f"{g_hi:.1f}</text>"
        f'<text x="{ml - 6}" y="{sg(g_lo) + 4:.1f}" font-size="11" text-anchor="end">'
        f"{g_lo:.1f}</text>"
        f'<text x="{ml + 4}" y="{mt + top_h + gap + 12}" font-size="11">Unloaded geometry (mm)'
        "</text>"
        f'<text x="{ml + 4}" y="{mt + 12}" font-size="11">Stiffness (% of nominal)</text>'
        f'<text x="{ml}" y="{height - 10}" font-size="11">{x0:.0f} m</text>'
        f'<text x="{ml + pw}" y="{height - 10}" font-size="11" text-anchor="end">{x1:.0f} m</text>'
        "</svg>"
    )
    return "".join(out)


def stiffness_section(window: StiffnessWindow, limits: Limits) -> str:
    """The report's "Stiffness" section (HTML)."""
    parts = ["<h2>Stiffness (separated from rail geometry)</h2>"]
    if window.message:
        parts.append(f'<p class="note"><strong>{escape(window.message)}</strong></p>')
    if not window.n:
        parts.append("<p>No aligned pass on this track yet.</p>")
        return "".join(parts)
    if not window.separable:
        parts.append(
            "<p>No stiffness figure is given: the passes of this track do not span enough "
            "wheel load anywhere, so a dip of the loaded profile may be rail geometry.</p>"
        )
    else:
        parts.append(stiffness_svg(window, limits))
        parts.append(
            f'<p class="note">{100 * window.separable_fraction:.0f} % of the covered track is '
            "separable. Points below nominal are coloured by the loss limit they reach; shaded: "
            "the separated soft spots.</p>"
        )
        if window.trust.provisional:
            parts.append(
                f'<p class="note"><strong>Provisional:</strong> {escape(window.trust.reason or "")}'
                f". To make it count: {escape(PROVISIONAL_REMEDY)}.</p>"
            )
        if window.spots:
            marks = [t.provisional for t in window.spot_trust] or [False] * len(window.spots)
            rows = "".join(
                f'<tr><td class="num">{km_m_range(s.start_m, s.end_m)}'
                + (" <strong>provisional</strong>" if mark else "")
                + f'</td><td class="num">{km_m(s.peak_m)}</td><td class="num">{s.loss_pct:.0f}</td>'
                f'<td class="num">{_band(s.loss_lo_pct, s.loss_hi_pct)}</td></tr>'
                for s, mark in zip(window.spots, marks, strict=True)
            )
            parts.append(
                '<table><thead><tr><th class="num">Extent (km+m)</th>'
                '<th class="num">Peak (km+m)</th>'
                '<th class="num">Loss (%)</th><th class="num">Band (%)</th></tr></thead>'
                f"<tbody>{rows}</tbody></table>"
            )
    if window.contributors:
        items = "".join(
            f"<li>{escape(c['kind'])} {c['id']}"
            + (f" ({escape(str(c['vehicle']))})" if c.get("vehicle") else "")
            + f": {c['mean_force_n'] / 1e3:.0f} kN per wheel</li>"
            for c in sorted(window.contributors, key=lambda c: c["mean_force_n"])
        )
        parts.append(f"<p>Contributing passes:</p><ul>{items}</ul>")
    return "".join(parts)


def _band(lo: float | None, hi: float | None) -> str:
    if lo is None or hi is None:
        return "—"
    return f"{lo:.0f}–{hi:.0f}"
