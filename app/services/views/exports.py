"""Exports: a run's profile and soft spots, a track's aggregated profile, defects and separated
stiffness as CSV, and the track report (HTML). Chainage aligned, m; levels mm; losses %.

Long exports stream: each writer is a generator that opens its own database session, so the
answer starts at once and memory stays flat whatever the window.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterable, Iterator, Sequence
from datetime import UTC, datetime
from typing import Any

import numpy as np
from sqlalchemy import func, select
from sqlalchemy.orm import Session

from app.db.models import Run, Track
from app.services.context import AppContext
from app.services.run_lifecycle.stored_runs import SpotOnTrack
from app.services.storage.profiles import iter_profile_rows, profile_blocks
from app.services.storage.retention import require_detail
from app.services.track.aggregate import read_track_profile
from app.services.track.quality import track_quality
from app.services.track.register import load_limits, provisional_notes, track_register
from app.services.track.separation_store import UPDATING, StiffnessWindow, stiffness_with_vehicles
from app.services.track.separation_trust import PROVISIONAL_REMEDY, Trust
from app.services.views.report import ReportInput, ReportRun, render_report
from app.services.views.report_quality import quality_section
from app.services.views.report_stiffness import stiffness_section
from app.services.views.window import Window
from engine.register import Defect

SOFT_SPOT_FIELDS = ("start_m", "end_m", "peak_m", "depth_mm", "stiffness_loss_pct")
DEFECT_CSV_FIELDS = (
    "priority", "id", "level", "level_since", "status", "start_m", "end_m", "peak_m",
    "depth_mm", "stiffness_loss_pct", "trend_mm_per_month", "trend_loss_pct_per_month",
    "runs_seen", "runs_covering", "first_seen", "last_seen", "stiffness_basis", "message",
    "stiffness_loss_lo_pct", "stiffness_loss_hi_pct", "evidence_text", "provisional",
    "provisional_reason",
)  # fmt: skip
DEFECT_FIELDS = tuple(
    f.name for f in dataclasses.fields(Defect) if f.name not in ("history", "evidence")
)
STIFFNESS_CSV_FIELDS = (
    "chainage_m", "k_rel", "k_rel_lo", "k_rel_hi", "geometry_mm", "geometry_sd_mm",
    "compliance_mm_per_kn", "n_passes", "load_ratio", "separable",
)  # fmt: skip
REPORT_RUNS = 200
"""Runs listed in the report (the newest)."""
_BATCH = 20_000


def csv_value(v: float | None, fmt: str) -> str:
    """A number as a CSV cell in ``fmt``; empty for None or NaN."""
    return "" if v is None or not math.isfinite(v) else format(v, fmt)


def run_profile_csv(
    ctx: AppContext, run: Run, window: Window, columns: tuple[str, ...]
) -> Iterator[str]:
    """A processed run's profile in a window as CSV lines (chainage aligned, 4 decimals).

    The stored blocks are read now (:class:`Gone` when retention removed them), decoded as
    the lines are sent."""
    off = run.offset_m
    lo, hi = window.stored(off)
    with ctx.db.session() as s:
        blocks = profile_blocks(s, run.id, lo, hi)
        require_detail(s, run, "profile")
    return _profile_lines(blocks, lo, hi, columns, off)


def _profile_lines(
    blocks: list[tuple[int, bytes]],
    lo: float | None,
    hi: float | None,
    columns: tuple[str, ...],
    off: float,
) -> Iterator[str]:
    yield ",".join(columns) + "\n"
    for rows in iter_profile_rows(blocks, lo, hi, columns):
        yield "".join(
            f"{r[0] + off:.4f}," + ",".join(csv_value(v, ".6f") for v in r[1:]) + "\n" for r in rows
        )


def soft_spots_csv(spots: Iterable[SpotOnTrack]) -> str:
    """Soft spots as CSV: extent and peak (m, 3 decimals), depth (mm), loss (%); a ``#`` line
    first with the message when the losses are withheld."""
    spots = list(spots)
    message = next((p.message for p in spots if p.message), None)
    lines = [f"# {message}"] if message else []
    lines.append(",".join(SOFT_SPOT_FIELDS))
    for p in spots:
        lines.append(
            f"{p.start_m:.3f},{p.end_m:.3f},{p.peak_m:.3f},{p.depth_mm:.6f},"
            f"{csv_value(p.stiffness_loss_pct, '.2f')}"
        )
    return "\n".join(lines) + "\n"


def _stiffness_cell(v: Any) -> str:
    if v is None:
        return ""
    if isinstance(v, bool):
        return "1" if v else "0"
    if isinstance(v, int):
        return str(v)
    return f"{v:.6g}"


def stiffness_csv(sep: StiffnessWindow) -> str:
    """A window of the separated stiffness as CSV (:data:`STIFFNESS_CSV_FIELDS`, 6 significant
    digits, ``separable`` 1/0), after ``#`` lines saying it is being redone, why points are
    not separable and why its separation is provisional."""
    provisional = (
        f"Provisional: {sep.trust.reason}; {PROVISIONAL_REMEDY} for it to count"
        if sep.trust.provisional
        else None
    )
    notes = (UPDATING if sep.updating else None, sep.message, provisional)
    lines = [f"# {note}" for note in notes if note]
    lines.append(",".join(STIFFNESS_CSV_FIELDS))
    cols = [sep.columns[k] for k in STIFFNESS_CSV_FIELDS]
    lines += [",".join(_stiffness_cell(c[i]) for c in cols) for i in range(sep.n)]
    return "\n".join(lines) + "\n"


def track_profile_csv(ctx: AppContext, track_id: int, window: Window) -> Iterator[str]:
    """A track's aggregated profile as CSV lines: ``chainage_m,level_mm,spread_mm,n_runs``."""
    yield "chainage_m,level_mm,spread_mm,n_runs\n"
    with ctx.db.session() as s:
        cols = read_track_profile(s, track_id, window.from_m, window.to_m)
    rows = zip(cols["chainage_m"], cols["level_mm"], cols["spread_mm"], cols["n_runs"], strict=True)
    batch: list[str] = []
    for c, lv, sp, n in rows:
        batch.append(f"{c:.2f},{lv:.6f},{sp:.6f},{n}\n")
        if len(batch) >= _BATCH:
            yield "".join(batch)
            batch = []
    yield "".join(batch)


def defect_dict(d: Defect, with_history: bool = False) -> dict[str, Any]:
    """A defect as JSON-ready values (``Defect.to_dict`` without deep-copying the history
    unless it is asked for: a large register answers in half the time)."""
    if with_history:
        return d.to_dict(with_history=True)
    out = {k: getattr(d, k) for k in DEFECT_FIELDS}
    for k in ("first_seen", "last_seen", "level_since"):
        if out[k] is not None:
            out[k] = out[k].isoformat()
    out["evidence"] = [e.to_dict() for e in d.evidence]
    out["evidence_text"] = d.evidence_text
    out["history"] = None  # DefectPublic declares it: sent as null when not asked for
    return out


def note_dict(note: tuple[str | None, str | None]) -> dict[str, str | None]:
    """What a defect's stiffness loss rests on and the message when there is none (see
    :func:`app.services.track.register.stiffness_notes`), as the defect's extra fields."""
    return {"stiffness_basis": note[0], "message": note[1]}


def defects_csv(
    defects: Sequence[Defect],
    notes: Sequence[tuple[str | None, str | None]],
    trust: Sequence[Trust],
) -> str:
    """The register as CSV, one defect a line in :data:`DEFECT_CSV_FIELDS` order (the
    texts quoted: they hold commas; ``provisional`` 1/0, see
    :func:`app.services.track.register.provisional_notes`)."""
    lines = [",".join(DEFECT_CSV_FIELDS)]
    for d, note, tr in zip(defects, notes, trust, strict=True):
        row = defect_dict(d) | note_dict(note) | tr.to_dict()
        cells = []
        for k in DEFECT_CSV_FIELDS:
            v = row[k]
            if isinstance(v, bool):
                cells.append("1" if v else "0")
            elif isinstance(v, float):
                cells.append(f"{v:.6g}" if math.isfinite(v) else "")
            elif k in ("message", "evidence_text", "provisional_reason") and v is not None:
                cells.append('"' + str(v).replace('"', '""') + '"')
            else:
                cells.append("" if v is None else str(v))
        lines.append(",".join(cells))
    return "\n".join(lines) + "\n"


def track_report(session: Session, trk: Track, top: int) -> str:
    """The self-contained HTML report of a track (see
    :func:`app.services.views.report.render_report`)."""
    limits, limits_row = load_limits(session, trk.id)
    defects = track_register(session, trk.id, limits)
    trust = provisional_notes(session, trk.id, defects)
    cols = read_track_profile(session, trk.id)
    count = select(func.count()).select_from(Run).where(Run.track_id == trk.id)
    runs_total = session.scalar(count) or 0
    runs = session.scalars(
        select(Run)
        .where(Run.track_id == trk.id)
        .order_by(func.coalesce(Run.recorded_at, Run.created_at).desc(), Run.id.desc())
        .limit(REPORT_RUNS)
    ).all()
    report_runs = []
    for r in runs:
        lo, hi = r.aligned_extent()
        report_runs.append(
            ReportRun(
                id=r.id,
                name=r.name,
                recorded_at=r.recorded_at,
                vehicle=r.vehicle.name,
                filename=r.original_filename,
                status=r.status,
                alignment_status=r.alignment_status,
                offset_m=r.offset_m,
                correlation=r.alignment_correlation,
                n_soft_spots=r.n_soft_spots,
                chainage_min_m=lo,
                chainage_max_m=hi,
            )  # fmt: skip
        )
    return render_report(
        ReportInput(
            track_name=trk.name,
            track_id=trk.id,
            description=trk.description,
            generated_at=datetime.now(UTC),
            defects=defects,
            provisional={
                d.id: t.reason or "" for d, t in zip(defects, trust, strict=True) if t.provisional
            },
            limits=limits,
            limits_are_default=limits_row is None,
            runs=report_runs,
            runs_total=int(runs_total),
            chainage_m=np.asarray(cols["chainage_m"], dtype=np.float64),
            level_mm=np.asarray(cols["level_mm"], dtype=np.float64),
            spread_mm=np.asarray(cols["spread_mm"], dtype=np.float64),
            stiffness_html=stiffness_section(stiffness_with_vehicles(session, trk.id), limits),
            quality_html=quality_section(track_quality(session, trk)),
            top=top,
        )
    )
