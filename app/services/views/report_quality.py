"""The HTML report's "Track quality (EN 13848)" section: D1/D2 section SDs with classes,
isolated defects against the speed-class limits, repeatability and the comparison with the
track's surveys. Made from the answer of :func:`app.services.track.quality.track_quality`; text and
tables only (no scripts), like the rest of the report."""

from __future__ import annotations

from html import escape
from typing import Any

MAX_ROWS = 200
"""Rows listed per table (a 40 km line has 200 sections of 200 m)."""


def _n(v: Any, digits: int = 2) -> str:
    return "—" if v is None else f"{v:.{digits}f}"


def _date(c: dict[str, Any] | None) -> str:
    if not c:
        return "—"
    if c["reached"]:
        return "reached"
    if not c["date"]:
        return "not growing"
    lo = c["earliest"][:10] if c["earliest"] else "?"
    hi = c["latest"][:10] if c["latest"] else "open"
    return f"{escape(c['level'])}: {c['date'][:10]} ({lo} – {hi})"


def quality_section(q: dict[str, Any]) -> str:
    """The section's HTML for a quality answer."""
    parts = ["<h2>Track quality (EN 13848)</h2>"]
    parts.append(
        '<p class="note">Longitudinal level filtered to D1 (3–25 m) and D2 '
        f"({q['d2_band_m'][0]:g}–{q['d2_band_m'][1]:g} m) by zero-phase Butterworth filters; "
        f"SD per {q['section_m']:g} m section; isolated defects mean to peak against the "
        "limits of the line speed's class"
        + (
            " (product defaults, not verified against EN 13848-5/-6: set the track's own)"
            if q["unverified_limits"]
            else ""
        )
        + ".</p>"
    )
    for note in q["notes"]:
        parts.append(f'<p class="note"><strong>{escape(note)}</strong></p>')
    secs = q["sections"][:MAX_ROWS]
    if not secs:
        parts.append("<p>No aligned pass on this track yet.</p>")
        return "".join(parts)
    rows = "".join(
        f'<tr><td class="num">{s["start_m"]:.0f}–{s["end_m"]:.0f}</td>'
        f'<td class="num">{_n(s["d1_sd_mm"])}</td><td class="num">{_n(s["d2_sd_mm"])}</td>'
        f'<td>{escape(s["quality_class"] or "—")}</td><td class="num">{s["n_passes"]}</td>'
        f'<td class="num">{_n(s["days_since_last_pass"], 0)}</td>'
        f'<td class="num">{_n(s["repeatability_d1_mm"])}</td>'
        f'<td class="num">{_n(s["speed_kmh"], 0)}</td><td>{escape(s["basis"])}</td>'
        f"<td>{_date(s.get('next_class'))}</td></tr>"
        for s in secs
    )
    parts.append(
        '<table><thead><tr><th class="num">Section (m)</th><th class="num">D1 SD (mm)</th>'
        '<th class="num">D2 SD (mm)</th><th>Class</th><th class="num">Passes</th>'
        '<th class="num">Days since last</th><th class="num">Repeatability (mm, 95 %)</th>'
        '<th class="num">Line speed (km/h)</th><th>Basis</th><th>Next class expected</th>'
        f"</tr></thead><tbody>{rows}</tbody></table>"
    )
    defects = q["defects"][:MAX_ROWS]
    if defects:
        rows = "".join(
            f'<tr><td class="num">{d["peak_m"]:.1f}</td><td>{escape(d["band"])}</td>'
            f'<td class="num">{d["value_mm"]:.2f}</td><td>{escape(d["level"])}</td>'
            f'<td class="num">{_n(d["speed_kmh"], 0)}</td><td>{escape(d["basis"])}</td>'
            f"<td>{_date(d.get('next_limit'))}</td></tr>"
            for d in defects
        )
        parts.append(
            f"<h3>Isolated defects ({len(q['defects'])})</h3>"
            '<table><thead><tr><th class="num">Peak (m)</th><th>Band</th>'
            '<th class="num">Value (mm)</th><th>Level</th><th class="num">Line speed (km/h)</th>'
            f"<th>Basis</th><th>Next limit expected</th></tr></thead><tbody>{rows}</tbody></table>"
        )
    else:
        parts.append("<p>No isolated defect reaches a limit.</p>")
    rep = q.get("repeatability")
    if rep and rep.get("r95_mm") is not None:
        parts.append(
            f"<p>Repeatability between passes ({rep['band_m'][0]:g}–{rep['band_m'][1]:g} m): "
            f"95 % of differences within {rep['r95_mm']:.2f} mm ({rep['n_pairs']} pairs).</p>"
        )
    parts += [_survey_table(sv) for sv in q.get("survey_comparison", [])]
    return "".join(parts)


def _survey_table(sv: dict[str, Any]) -> str:
    """A survey's comparison with the fleet, section by section (mm)."""
    rows = "".join(
        f'<tr><td class="num">{r["start_m"]:.0f}–{r["end_m"]:.0f}</td>'
        f'<td class="num">{_n(r["survey_d1_sd_mm"])}</td>'
        f'<td class="num">{_n(r["fleet_d1_sd_mm"])}</td>'
        f'<td class="num">{_n(r["d1_sd_diff_mm"])}</td>'
        f'<td class="num">{_n(r["d2_sd_diff_mm"])}</td>'
        f'<td class="num">{_n(r["d1_peak_error_mm"])}</td></tr>'
        for r in sv["sections"][:MAX_ROWS]
    )
    name = escape(sv["name"] or f"survey {sv['survey_id']}")
    return (
        f"<h3>Against the recording car: {name}</h3>"
        '<table><thead><tr><th class="num">Section (m)</th><th class="num">Survey D1 SD</th>'
        '<th class="num">Fleet D1 SD</th><th class="num">D1 SD difference</th>'
        '<th class="num">D2 SD difference</th><th class="num">D1 peak error</th></tr>'
        f"</thead><tbody>{rows}</tbody></table>"
        '<p class="note">mm; fleet minus survey over the points both cover.</p>'
    )
