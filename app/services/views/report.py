"""The per-track report: one self-contained HTML page (inline SVG chainage map, no scripts,
no external resources) with the top defects, the limits and the runs.

Every piece of user text (track, run, vehicle and file names, descriptions) goes through
``html.escape``; numbers are formatted here. Chainage in m, levels and depths in mm.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from datetime import datetime
from html import escape

import numpy as np
from numpy.typing import NDArray

from app.services.track.separation_trust import PROVISIONAL_REMEDY
from app.services.views.notation import km_m, km_m_range
from engine.decimate import minmax_indices
from engine.register import LEVELS, Defect, Limits

REPORT_MAX_POINTS = 1400
"""Most profile points drawn in the report's SVG (each 700 buckets' lowest and highest)."""

REPORT_CSP = (
    "default-src 'none'; style-src 'unsafe-inline'; img-src data:; base-uri 'none'; "
    "form-action 'none'; frame-ancestors 'none'"
)
"""The report needs nothing but its own inline style: everything else is refused."""

LEVEL_STYLE = {
    # fill, stroke, marker: colour plus shape, so the map reads without colour vision
    "immediate": ("#b2182b", "#67001f", "triangle"),
    "intervention": ("#ef8a62", "#8c2d04", "diamond"),
    "alert": ("#fddb6d", "#7f5f00", "square"),
    None: ("#d1d5db", "#4b5563", "circle"),
}
LEVEL_NAMES = {
    "immediate": "Immediate action",
    "intervention": "Intervention",
    "alert": "Alert",
    None: "Below limits",
}


@dataclass(frozen=True)
class ReportRun:
    """A run as listed in the report (user text raw here; escaped when rendered)."""

    id: int
    name: str | None
    recorded_at: datetime | None
    vehicle: str
    filename: str | None
    status: str
    alignment_status: str | None
    offset_m: float
    correlation: float | None
    n_soft_spots: int | None
    chainage_min_m: float | None
    chainage_max_m: float | None


@dataclass(frozen=True)
class ReportInput:
    """Everything the report shows."""

    track_name: str
    track_id: int
    description: str | None
    generated_at: datetime
    defects: Sequence[Defect]
    limits: Limits
    limits_are_default: bool
    runs: Sequence[ReportRun]
    runs_total: int
    chainage_m: NDArray[np.float64]
    level_mm: NDArray[np.float64]
    spread_mm: NDArray[np.float64]
    top: int = 25
    stiffness_html: str = ""
    """The stiffness section (``app.services.views.report_stiffness``), placed after the map."""
    quality_html: str = ""
    """The track quality section (``app.services.views.report_quality``), after the stiffness."""
    provisional: Mapping[str, str] = field(default_factory=dict)
    """The reason of each provisional defect, by id
    (``app.services.track.register.provisional_notes``)."""


def _num(v: float | None, digits: int = 2) -> str:
    if v is None or not math.isfinite(v):
        return "—"
    return f"{v:.{digits}f}"


def _signed(v: float | None, digits: int = 2) -> str:
    if v is None or not math.isfinite(v):
        return "—"
    return f"{v:+.{digits}f}"


def _day(v: datetime | None) -> str:
    return "—" if v is None else f"{v:%Y-%m-%d}"


def _nice_step(span: float, target: int) -> float:
    raw = span / max(target, 1)
    if raw <= 0 or not math.isfinite(raw):
        return 1.0
    mag = 10 ** math.floor(math.log10(raw))
    for m in (1, 2, 2.5, 5, 10):
        if raw <= m * mag:
            return m * mag
    return 10 * mag


def _ticks(lo: float, hi: float, target: int) -> Iterator[float]:
    """An axis's tick values from ``lo`` to ``hi``: about ``target`` of them, a round step
    apart."""
    step = _nice_step(hi - lo, target)
    v = math.ceil(lo / step) * step
    while v <= hi:
        yield v
        v += step


def _marker(shape: str, x: float, y: float, r: float, fill: str, stroke: str) -> str:
    if shape == "triangle":
        pts = f"{x:.1f},{y - r:.1f} {x + r:.1f},{y + r * 0.8:.1f} {x - r:.1f},{y + r * 0.8:.1f}"
        return f'<polygon points="{pts}" fill="{fill}" stroke="{stroke}" stroke-width="1.2"/>'
    if shape == "diamond":
        pts = f"{x:.1f},{y - r:.1f} {x + r:.1f},{y:.1f} {x:.1f},{y + r:.1f} {x - r:.1f},{y:.1f}"
        return f'<polygon points="{pts}" fill="{fill}" stroke="{stroke}" stroke-width="1.2"/>'
    if shape == "square":
        s = r * 0.85
        return (
            f'<rect x="{x - s:.1f}" y="{y - s:.1f}" width="{2 * s:.1f}" height="{2 * s:.1f}" '
            f'fill="{fill}" stroke="{stroke}" stroke-width="1.2"/>'
        )
    return (
        f'<circle cx="{x:.1f}" cy="{y:.1f}" r="{r * 0.8:.1f}" fill="{fill}" stroke="{stroke}" '
        f'stroke-width="1.2"/>'
    )


@dataclass(frozen=True)
class _MapFrame:
    """The chainage map's layout (px) and its chainage range (m)."""

    x0: float
    x1: float
    width: int
    ml: int = 64
    mr: int = 16
    mt: int = 16
    prof_h: int = 220
    strip_h: int = 70
    axis_h: int = 44

    @property
    def pw(self) -> int:
        return self.width - self.ml - self.mr

    @property
    def height(self) -> int:
        return self.mt + self.prof_h + self.strip_h + self.axis_h

    def sx(self, v: float) -> float:
        return self.ml + (v - self.x0) / (self.x1 - self.x0) * self.pw


def _gap_segments(
    c: NDArray[np.float64], lv: NDArray[np.float64], max_gap_m: float
) -> list[list[int]]:
    """Indices of the runs of finite levels, split where chainage jumps over ``max_gap_m``."""
    seg: list[int] = []
    segments: list[list[int]] = []
    for k in range(c.size):
        if np.isfinite(lv[k]) and (not seg or c[k] - c[seg[-1]] <= max_gap_m):
            seg.append(k)
        else:
            if len(seg) > 1:
                segments.append(seg)
            seg = [k] if np.isfinite(lv[k]) else []
    if len(seg) > 1:
        segments.append(seg)
    return segments


def _profile_panel(
    f: _MapFrame,
    chainage_m: NDArray[np.float64],
    level_mm: NDArray[np.float64],
    spread_mm: NDArray[np.float64],
    defects: Sequence[Defect],
    ranks: dict[str, int],
) -> list[str]:
    """The aggregated level with its spread band (split at gaps), its level axis, and the
    50 first-ranked defects as markers on it."""
    ml, mt, prof_h, pw = f.ml, f.mt, f.prof_h, f.pw
    finite = np.isfinite(level_mm)
    keep = minmax_indices(np.where(finite, level_mm, np.nan), REPORT_MAX_POINTS)
    c = chainage_m[keep]
    lv = level_mm[keep]
    sp = np.nan_to_num(spread_mm[keep], nan=0.0)
    lo_all = np.nanmin(lv - sp)
    hi_all = np.nanmax(lv + sp)
    if not hi_all > lo_all:
        lo_all, hi_all = lo_all - 0.1, hi_all + 0.1
    ypad = 0.08 * (hi_all - lo_all)
    y0, y1 = lo_all - ypad, hi_all + ypad

    def sy(v: float) -> float:
        return mt + prof_h - (v - y0) / (y1 - y0) * prof_h

    sx = f.sx
    out: list[str] = []
    segments = _gap_segments(c, lv, 5 * (f.x1 - f.x0) / pw + 1.0)
    for s in segments:
        upper = " ".join(f"{sx(c[k]):.1f},{sy(lv[k] + sp[k]):.1f}" for k in s)
        lower = " ".join(f"{sx(c[k]):.1f},{sy(lv[k] - sp[k]):.1f}" for k in reversed(s))
        out.append(f'<polygon points="{upper} {lower}" fill="#bfdbfe" stroke="none"/>')
    for s in segments:
        pts = " ".join(f"{sx(c[k]):.1f},{sy(lv[k]):.1f}" for k in s)
        out.append(f'<polyline points="{pts}" fill="none" stroke="#1d4ed8" stroke-width="1"/>')
    for v in _ticks(y0, y1, 4):
        y = sy(v)
        out.append(
            f'<line x1="{ml - 4}" y1="{y:.1f}" x2="{ml + pw}" y2="{y:.1f}" stroke="#e2e8f0"/>'
            f'<text x="{ml - 6}" y="{y + 4:.1f}" font-size="11" text-anchor="end">'
            f"{v:g}</text>"
        )
    out.append(
        f'<text x="14" y="{mt + prof_h / 2:.0f}" font-size="12" text-anchor="middle" '
        f'transform="rotate(-90 14 {mt + prof_h / 2:.0f})">Level (mm)</text>'
    )
    for d in defects:
        rank = ranks[d.id]
        if rank > 50:
            continue
        fill, stroke, shape = LEVEL_STYLE[d.level]
        k = int(np.argmin(np.abs(c - d.peak_m))) if c.size else 0
        y = sy(float(lv[k])) if c.size and np.isfinite(lv[k]) else mt + prof_h - 10
        out.append(_marker(shape, sx(d.peak_m), y, 6.5, fill, stroke))
    return out


def _defect_strip(f: _MapFrame, defects: Sequence[Defect], ranks: dict[str, int]) -> list[str]:
    """The defects' extents as bars in up to four lanes, labelled with the rank of the table
    below (the first 20)."""
    ml, sy0 = f.ml, f.mt + f.prof_h + 10
    out = [f'<text x="{ml - 6}" y="{sy0 + 26}" font-size="11" text-anchor="end">Defects</text>']
    lanes: list[float] = []
    for d in sorted(defects, key=lambda d: d.start_m):
        rank = ranks[d.id]
        fill, stroke, _ = LEVEL_STYLE[d.level]
        xa, xb = f.sx(d.start_m), max(f.sx(d.end_m), f.sx(d.start_m) + 3)
        lane = next((i for i, end in enumerate(lanes) if end < xa - 2), None)
        if lane is None:
            lane = len(lanes)
            lanes.append(0.0)
        lanes[lane] = xb + (18 if rank <= 20 else 0)
        y = sy0 + 4 + (lane % 4) * 14
        out.append(
            f'<rect x="{xa:.1f}" y="{y:.1f}" width="{xb - xa:.1f}" height="10" fill="{fill}" '
            f'stroke="{stroke}"/>'
        )
        if rank <= 20:
            out.append(f'<text x="{xb + 2:.1f}" y="{y + 9:.1f}" font-size="10">{rank}</text>')
    return out


def _chainage_axis(f: _MapFrame) -> list[str]:
    ml, pw, ya = f.ml, f.pw, f.mt + f.prof_h + f.strip_h
    out = [f'<line x1="{ml}" y1="{ya}" x2="{ml + pw}" y2="{ya}" stroke="#475569"/>']
    for v in _ticks(f.x0, f.x1, 8):
        x = f.sx(v)
        out.append(
            f'<line x1="{x:.1f}" y1="{ya}" x2="{x:.1f}" y2="{ya + 5}" stroke="#475569"/>'
            f'<text x="{x:.1f}" y="{ya + 18}" font-size="11" text-anchor="middle">{v:g}</text>'
        )
    out.append(
        f'<text x="{ml + pw / 2:.0f}" y="{ya + 36}" font-size="12" text-anchor="middle">'
        "Chainage (m, aligned)</text></svg>"
    )
    return out


def chainage_map_svg(
    chainage_m: NDArray[np.float64],
    level_mm: NDArray[np.float64],
    spread_mm: NDArray[np.float64],
    defects: Sequence[Defect],
    ranks: dict[str, int],
    width: int = 1000,
) -> str:
    """The chainage map: aggregated level with its spread band, defects as ranked markers."""
    xs = [float(d.start_m) for d in defects] + [float(d.end_m) for d in defects]
    finite = np.isfinite(level_mm)
    if finite.any():
        xs += [float(chainage_m[finite][0]), float(chainage_m[finite][-1])]
    if not xs:
        return (
            f'<svg xmlns="http://www.w3.org/2000/svg" width="{width}" height="60" role="img" '
            'aria-label="No aligned runs yet"><text x="10" y="35" font-size="14">No aligned '
            "run on this track yet: nothing to map.</text></svg>"
        )
    x0, x1 = min(xs), max(xs)
    if x1 - x0 < 1:
        x0, x1 = x0 - 5, x1 + 5
    pad = 0.01 * (x1 - x0)
    f = _MapFrame(x0 - pad, x1 + pad, width)
    out = [
        f'<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 {width} {f.height}" '
        f'width="100%" role="img" aria-labelledby="map-title">'
        '<title id="map-title">Chainage map: aggregated loaded profile with its spread, '
        "and the defects of the register by priority</title>",
        f'<rect x="{f.ml}" y="{f.mt}" width="{f.pw}" height="{f.prof_h}" fill="#f8fafc" '
        'stroke="#cbd5e1"/>',
    ]
    if finite.any():
        out += _profile_panel(f, chainage_m, level_mm, spread_mm, defects, ranks)
    else:
        out.append(
            f'<text x="{f.ml + 10}" y="{f.mt + 24}" font-size="13">'
            "No aggregated profile yet.</text>"
        )
    return "".join(out + _defect_strip(f, defects, ranks) + _chainage_axis(f))


def _legend() -> str:
    items = []
    for level in (*LEVELS, None):
        fill, stroke, shape = LEVEL_STYLE[level]
        svg = (
            '<svg xmlns="http://www.w3.org/2000/svg" width="16" height="16" aria-hidden="true">'
            f"{_marker(shape, 8, 8, 6, fill, stroke)}</svg>"
        )
        items.append(f"<li>{svg} {escape(LEVEL_NAMES[level])}</li>")
    items.append(
        '<li><svg xmlns="http://www.w3.org/2000/svg" width="22" height="12" aria-hidden="true">'
        '<rect width="22" height="12" fill="#bfdbfe"/><line x1="0" y1="6" x2="22" y2="6" '
        'stroke="#1d4ed8"/></svg> Median level ± robust spread of the aligned runs</li>'
    )
    return '<ul class="legend">' + "".join(items) + "</ul>"


STYLE = """
body{font-family:system-ui,-apple-system,"Segoe UI",Roboto,sans-serif;color:#1b1f24;
margin:24px auto;max-width:1100px;padding:0 16px;line-height:1.4}
h1{font-size:1.6rem;margin:0 0 4px}h2{font-size:1.2rem;margin:28px 0 8px}
.meta{color:#475569;margin:0 0 12px}table{border-collapse:collapse;width:100%;font-size:.9rem}
th,td{border-bottom:1px solid #e2e8f0;padding:4px 6px;text-align:left;vertical-align:top}
td.num{white-space:nowrap}
th{background:#f1f5f9}td.num,th.num{text-align:right;font-variant-numeric:tabular-nums}
.legend{list-style:none;padding:0;display:flex;flex-wrap:wrap;gap:14px;font-size:.85rem}
.legend li{display:flex;align-items:center;gap:4px}.lvl{font-weight:600}
.lvl-immediate{color:#8a0f24}.lvl-intervention{color:#8c2d04}.lvl-alert{color:#6b5000}
.note{color:#475569;font-size:.85rem}
@media print{body{margin:0;max-width:none}h2{break-after:avoid}tr{break-inside:avoid}}
"""


def _loss_band(d: Defect) -> str:
    """The loss with its band where the evidence gives one: ``46 (38–55)``."""
    if d.stiffness_loss_lo_pct is None or d.stiffness_loss_hi_pct is None:
        return _num(d.stiffness_loss_pct, 0)
    return (
        f"{_num(d.stiffness_loss_pct, 0)} ({_num(d.stiffness_loss_lo_pct, 0)}–"
        f"{_num(d.stiffness_loss_hi_pct, 0)})"
    )


def _defects_table(data: ReportInput, defects: list[Defect], ranks: dict[str, int]) -> list[str]:
    """The top defects' table (or why there is none)."""
    parts: list[str] = []
    parts.append(f"<h2>Top defects ({min(len(defects), data.top)} of {len(defects)})</h2>")
    shown = [d.id for d in defects[: data.top] if d.id in data.provisional]
    if shown:
        reasons = "; ".join(dict.fromkeys(data.provisional[i] for i in shown))
        parts.append(
            f'<p class="note"><strong>Provisional</strong> ({len(shown)} of the defects below, '
            "separated with vehicles whose parameters or loads are not known): "
            f"{escape(reasons)}. To make them count: {escape(PROVISIONAL_REMEDY)}.</p>"
        )
    if defects:
        rows = []
        for d in defects[: data.top]:
            lv = d.level
            lvl = (
                f'<span class="lvl lvl-{lv}">{escape(LEVEL_NAMES[lv])}</span>'
                if lv
                else escape(LEVEL_NAMES[None])
            )
            rows.append(
                "<tr>"
                f'<td class="num">{ranks[d.id]}</td><td class="num">{d.priority}</td>'
                f"<td>{lvl}</td><td>{escape(d.status)}</td>"
                f'<td class="num">{km_m_range(d.start_m, d.end_m)}</td>'
                f'<td class="num">{km_m(d.peak_m)}</td>'
                f'<td class="num">{_num(d.depth_mm, 3)}</td>'
                f'<td class="num">{_loss_band(d)}</td>'
                f'<td class="num">{_signed(d.trend_mm_per_month, 3)}</td>'
                f'<td class="num">{_signed(d.trend_loss_pct_per_month, 1)}</td>'
                f"<td>{escape(d.evidence_text)} ({d.runs_seen} of {d.runs_covering} covering)"
                + ("; <strong>provisional</strong>" if d.id in data.provisional else "")
                + "</td>"
                f"<td>{_day(d.first_seen)}</td><td>{_day(d.last_seen)}</td>"
                f"<td>{_day(d.level_since)}</td><td>{escape(d.id)}</td></tr>"
            )
        parts.append(
            "<table><thead><tr>"
            '<th class="num">#</th><th class="num">Priority</th><th>Level</th><th>Status</th>'
            '<th class="num">Extent (km+m)</th><th class="num">Peak (km+m)</th>'
            '<th class="num">Depth (mm)</th><th class="num">Loss (%)</th>'
            '<th class="num">Trend (mm/month)</th><th class="num">Trend (%/month)</th>'
            "<th>Evidence</th><th>First seen</th><th>Last seen</th>"
            "<th>Level since</th><th>Id</th></tr></thead><tbody>"
            + "".join(rows)
            + "</tbody></table>"
        )
    else:
        parts.append("<p>No defect: no aligned run of this track found a soft spot.</p>")
    return parts


def _limits_table(data: ReportInput) -> list[str]:
    """The limits each level is reached at."""
    parts: list[str] = []
    lim = data.limits
    parts.append(
        "<h2>Limits</h2>"
        + (
            '<p class="note">The default limits (the track has none of its own).</p>'
            if data.limits_are_default
            else ""
        )
        + '<table><thead><tr><th>Level</th><th class="num">Depth (mm)</th>'
        '<th class="num">Stiffness loss (%)</th></tr></thead><tbody>'
        + "".join(
            f"<tr><td>{escape(LEVEL_NAMES[lv])}</td>"
            f'<td class="num">{_num(getattr(lim, f"{lv}_depth_mm"), 3)}</td>'
            f'<td class="num">{_num(getattr(lim, f"{lv}_loss_pct"), 1)}</td></tr>'
            for lv in reversed(LEVELS)
        )
        + "</tbody></table>"
        '<p class="note">A defect reaches a level when its depth or its stiffness loss in the '
        "latest run reaches that level's value (— : criterion not used).</p>"
    )
    return parts


def _runs_table(data: ReportInput) -> list[str]:
    """The newest runs of the track: alignment, extent, soft spots."""
    parts: list[str] = []
    parts.append(
        f"<h2>Runs ({len(data.runs)}"
        + (f" newest of {data.runs_total}" if data.runs_total > len(data.runs) else "")
        + ")</h2>"
    )
    if data.runs:
        rows = []
        for r in data.runs:
            rows.append(
                "<tr>"
                f'<td class="num">{r.id}</td><td>{escape(r.name or "")}</td>'
                f"<td>{'—' if r.recorded_at is None else f'{r.recorded_at:%Y-%m-%d %H:%M}'}</td>"
                f"<td>{escape(r.vehicle)}</td><td>{escape(r.filename or '')}</td>"
                f"<td>{escape(r.status)}</td><td>{escape(r.alignment_status or '—')}</td>"
                f'<td class="num">{_signed(r.offset_m, 2)}</td>'
                f'<td class="num">{_num(r.correlation, 2)}</td>'
                f'<td class="num">{km_m_range(r.chainage_min_m, r.chainage_max_m)}</td>'
                f'<td class="num">{"—" if r.n_soft_spots is None else r.n_soft_spots}</td></tr>'
            )
        parts.append(
            "<table><thead><tr>"
            '<th class="num">Run</th><th>Name</th><th>Recorded (UTC)</th><th>Vehicle</th>'
            "<th>File</th><th>Status</th><th>Alignment</th>"
            '<th class="num">Offset (m)</th><th class="num">Correlation</th>'
            '<th class="num">Extent (km+m, aligned)</th><th class="num">Soft spots</th>'
            "</tr></thead><tbody>" + "".join(rows) + "</tbody></table>"
        )
    else:
        parts.append("<p>No run on this track yet.</p>")
    return parts


def render_report(data: ReportInput) -> str:
    """The HTML report of a track (a complete document, UTF-8)."""
    defects = list(data.defects)
    ranks = {d.id: i + 1 for i, d in enumerate(defects)}
    counts = {lv: sum(1 for d in defects if d.level == lv) for lv in LEVELS}
    name = escape(data.track_name)
    parts = [
        "<!DOCTYPE html>",
        '<html lang="en"><head><meta charset="utf-8">',
        '<meta name="viewport" content="width=device-width, initial-scale=1">',
        f"<title>Track report: {name}</title><style>{STYLE}</style></head><body>",
        f"<h1>Track report: {name}</h1>",
        f'<p class="meta">Track id {data.track_id}'
        + (f" · {escape(data.description)}" if data.description else "")
        + f" · generated {data.generated_at:%Y-%m-%d %H:%M} UTC · {data.runs_total} run"
        + ("s" if data.runs_total != 1 else "")
        + f" · {len(defects)} defect"
        + ("s" if len(defects) != 1 else "")
        + f" ({counts['immediate']} immediate action, {counts['intervention']} intervention, "
        f"{counts['alert']} alert)</p>",
        "<h2>Chainage map</h2>",
        chainage_map_svg(data.chainage_m, data.level_mm, data.spread_mm, defects, ranks),
        _legend(),
        '<p class="note">Levels are the loaded profile (mm, positive up): a soft spot is a dip. '
        "Bars under the profile are the defects' extents, numbered as in the table.</p>",
        data.stiffness_html,
        data.quality_html,
    ]
    parts += _defects_table(data, defects, ranks)
    parts += _limits_table(data)
    parts += _runs_table(data)
    parts.append(
        '<p class="note">Alignment: each run is cross-correlated with the aggregated profile of '
        "the runs before it; an unaligned run is shown as logged and left out of the aggregate "
        "and the register.</p></body></html>"
    )
    return "".join(parts)
