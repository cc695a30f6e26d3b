"""Reference surveys: a track recording car's longitudinal level at a known wheel load.

A survey is read from a small CSV (``chainage_m,level_mm``, level positive up), checked in full
before anything is written, put on a 0.25 m grid and band-passed to the product's wavelength
band (as far as the survey's own band reaches), aligned to the track like a run
(``app.services.track.alignment``) and kept on the track grid (``survey_levels``). The track's
geometry/stiffness separation then counts it as one more pass at its wheel load.

Units: chainage m, level mm, wheel load N, wavelengths m.
"""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Iterator
from dataclasses import dataclass
from datetime import datetime

import numpy as np
from numpy.typing import NDArray
from sqlalchemy import delete, func, insert, select
from sqlalchemy.orm import Session

from app.db.models import Survey, SurveyLevels, Track
from app.services.context import AppContext
from app.services.errors import Invalid, NotFound, TooLarge
from app.services.lookup import get_track
from app.services.run_lifecycle.logs import sha256_hex
from app.services.storage.packing import pack_f4
from app.services.track.aggregate import chunked
from app.services.track.alignment import GRID_STEP_M, MIN_OVERLAP_M, align_to_track, on_track_grid
from app.services.track.integrate import lock_track
from app.services.track.separation_store import recompute_all, recompute_stiffness
from engine.chainage import bandpass_distance
from engine.pipeline import ProcessConfig

SURVEY_COLUMNS = ("chainage_m", "level_mm")
"""Columns a survey CSV must have (header row; other columns are ignored)."""

MAX_LEVEL_MM = 100.0
"""Largest plausible longitudinal level in the 1-200 m band, mm (EN 13848-5 immediate-action
limits are ~30 mm): a bigger value is a unit or sign-convention mistake, not track."""

MAX_POINTS = 2_000_000
"""Most rows a survey may have (500 km at 0.25 m)."""

_PRODUCT = ProcessConfig()


@dataclass(frozen=True)
class SurveyInput:
    """What comes with a survey file (validated by the schema)."""

    wheel_load_n: float
    band_min_m: float
    band_max_m: float
    name: str | None = None
    recorded_at: datetime | None = None
    filename: str | None = None


def _bad(message: str, *, column: str | None = None, row: int | None = None) -> Invalid:
    return Invalid(message, field="file", column=column, row=row)


def parse_survey_csv(data: bytes | bytearray) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Chainage (m) and level (mm) of a survey CSV; Invalid naming the column and row otherwise.

    Rows are numbered like the file's lines (header = 1). Chainage must be strictly monotonic
    (increasing or decreasing), every value finite, and every level within
    +-:data:`MAX_LEVEL_MM`.
    """
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError:
        raise _bad("the survey is not UTF-8 text (a CSV with chainage_m,level_mm)") from None
    reader = csv.reader(io.StringIO(text))
    try:
        return _parse_rows(reader)
    except csv.Error as exc:
        # the csv module's own limits (a field over 128 KB, a NUL byte): no survey has them
        raise _bad(
            f"row {reader.line_num}: not a readable CSV row ({exc}); expected numbers "
            "chainage_m,level_mm",
            row=reader.line_num,
        ) from None


def _parse_rows(reader: Iterator[list[str]]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    header = next(reader, None)
    if header is None or not any(h.strip() for h in header):
        raise _bad("the survey is empty: expected a header chainage_m,level_mm and rows")
    names = [h.strip().lower() for h in header]
    index = {}
    for col in SURVEY_COLUMNS:
        if col not in names:
            raise _bad(
                f"the survey has no column {col!r} (columns found: {', '.join(names)}); "
                "expected chainage_m (m) and level_mm (mm, positive up)",
                column=col,
                row=1,
            )
        index[col] = names.index(col)
    x: list[float] = []
    y: list[float] = []
    for line, cells in enumerate(reader, start=2):
        if not cells or not any(c.strip() for c in cells):
            continue
        if len(x) >= MAX_POINTS:
            raise _bad(f"the survey has more than {MAX_POINTS} rows", row=line)
        for col, out in (("chainage_m", x), ("level_mm", y)):
            j = index[col]
            cell = cells[j].strip() if j < len(cells) else ""
            try:
                v = float(cell)
            except ValueError:
                raise _bad(
                    f"row {line}: {col} {cell!r} is not a number" if cell
                    else f"row {line}: {col} is empty",
                    column=col, row=line,
                ) from None  # fmt: skip
            if not math.isfinite(v):
                raise _bad(f"row {line}: {col} is {cell} (not finite)", column=col, row=line)
            out.append(v)
        if abs(y[-1]) > MAX_LEVEL_MM:
            raise _bad(
                f"row {line}: level_mm {y[-1]:g} mm is beyond +-{MAX_LEVEL_MM:g} mm: not a "
                "longitudinal level (levels are in mm, relative to the mean line)",
                column="level_mm", row=line,
            )  # fmt: skip
    if len(x) < 2:
        raise _bad("the survey has fewer than two rows", row=len(x) + 2)
    xa, ya = np.asarray(x), np.asarray(y)
    step = np.diff(xa)
    sign = 1.0 if step[0] > 0 else -1.0
    bad = np.flatnonzero(step * sign <= 0)
    if bad.size:
        i = int(bad[0])
        raise _bad(
            f"row {i + 3}: chainage_m {xa[i + 1]:g} m does not continue the "
            f"{'increasing' if sign > 0 else 'decreasing'} chainage of row {i + 2} "
            f"({xa[i]:g} m): chainage must be strictly monotonic",
            column="chainage_m", row=i + 3,
        )  # fmt: skip
    if sign < 0:
        xa, ya = xa[::-1], ya[::-1]
    return xa, ya


def check_survey(x: NDArray[np.float64], meta: SurveyInput) -> None:
    """Sampling and extent against the survey's band; Invalid naming what is wrong."""
    length = float(x[-1] - x[0])
    if length < MIN_OVERLAP_M:
        raise _bad(
            f"the survey covers {length:.1f} m; at least {MIN_OVERLAP_M:g} m are needed to "
            "align it to the track", column="chainage_m",
        )  # fmt: skip
    gaps = np.diff(x)
    worst = int(np.argmax(gaps))
    limit = meta.band_min_m / 4.0
    if gaps[worst] > limit:
        raise _bad(
            f"row {worst + 3}: chainage_m jumps {gaps[worst]:.3g} m; the survey's band starts at "
            f"{meta.band_min_m:g} m, so samples must be at most {limit:.3g} m apart",
            column="chainage_m", row=worst + 3,
        )  # fmt: skip


def band_of(meta: SurveyInput) -> tuple[float, float]:
    """The wavelength band (m) a survey takes part in: its own within the product's."""
    return (
        max(meta.band_min_m, _PRODUCT.lambda_min_m),
        min(meta.band_max_m, _PRODUCT.lambda_max_m),
    )


def survey_level_on_grid(
    x: NDArray[np.float64], level_mm: NDArray[np.float64], meta: SurveyInput
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The survey on a 0.25 m grid of its own chainage, band-passed like a run's profile."""
    grid = np.arange(math.ceil(x[0] / GRID_STEP_M), math.floor(x[-1] / GRID_STEP_M) + 1)
    grid = grid * GRID_STEP_M
    level = np.interp(grid, x, level_mm)
    lo, hi = band_of(meta)
    return grid, bandpass_distance(level, GRID_STEP_M, lo, hi)


def create_survey(
    session: Session, track: Track, data: bytes | bytearray, meta: SurveyInput
) -> tuple[Survey, bool]:
    """Check, store, align and separate with a survey; ``(survey, created)`` (caller commits).

    The same file on the same track returns the stored survey (``created`` False).

    Raises
    ------
    Invalid
        Naming the column and row (or field) of a bad survey; nothing is stored.
    """
    x, y = parse_survey_csv(data)
    check_survey(x, meta)
    digest = sha256_hex(data)
    prev = session.scalar(
        select(Survey).where(Survey.track_id == track.id, Survey.content_hash == digest)
    )
    if prev is not None:
        return prev, False
    grid, level = survey_level_on_grid(x, y, meta)
    buf = io.BytesIO()
    np.savez(buf, chainage_m=x, level_mm=y)
    lock_track(session, track.id)
    al = align_to_track(session, track.id, grid, level)
    survey = Survey(
        track_id=track.id, name=meta.name, original_filename=meta.filename,
        recorded_at=meta.recorded_at, wheel_load_n=meta.wheel_load_n,
        band_min_m=meta.band_min_m, band_max_m=meta.band_max_m, n_points=int(x.size),
        chainage_min_m=float(x[0]), chainage_max_m=float(x[-1]),
        chainage_offset_m=al.offset_m, alignment_status=al.status,
        alignment_correlation=al.correlation, alignment_reason=al.reason,
        content_hash=digest, data=buf.getvalue(),
    )  # fmt: skip
    session.add(survey)
    session.flush()
    chunks = _place(session, survey, grid, level)
    if chunks is not None:
        recompute_stiffness(session, track.id, *chunks)
    return survey, True


def import_survey(
    ctx: AppContext, track: str, data: bytes | bytearray, meta: SurveyInput
) -> tuple[Survey, bool]:
    """:func:`create_survey` on the track whose id or name is ``track``, in a transaction of
    its own (committed); ``(survey, created)``.

    Raises
    ------
    TooLarge
        When the file is over the upload limit (``TRACKPROFILE_MAX_UPLOAD_MB``).
    """
    limit = ctx.settings.max_upload_bytes
    if len(data) > limit:
        raise TooLarge(
            f"the survey is larger than the upload limit ({limit} bytes)", limit_bytes=limit
        )
    with ctx.db.session() as s:
        survey, created = create_survey(s, get_track(s, track), data, meta)
        s.commit()
        return survey, created


def _place(
    session: Session, survey: Survey, grid: NDArray[np.float64], level: NDArray[np.float64]
) -> tuple[int, int] | None:
    """Keep an aligned survey's level on the track grid; the chunks written (None: none)."""
    if survey.alignment_status not in ("reference", "aligned"):
        return None
    i_lo, levels = on_track_grid(grid, level, survey.chainage_offset_m)
    c_lo, c_hi, parts = chunked(i_lo, levels)
    if not parts:
        return None
    session.execute(
        insert(SurveyLevels),
        [{"survey_id": survey.id, "chunk": c, "track_id": survey.track_id,
          "levels": pack_f4(buf32)} for c, buf32 in parts.items()],
    )  # fmt: skip
    return c_lo, c_hi


def realign_surveys(session: Session, track_id: int) -> list[Survey]:
    """Align every survey of a track again against its (rebuilt) aggregated profile and
    separate the whole track again (after ``integrate.realign_track``; caller commits)."""
    lock_track(session, track_id)
    session.execute(delete(SurveyLevels).where(SurveyLevels.track_id == track_id))
    surveys = list_surveys(session, track_id)
    for survey in surveys:
        raw = np.load(io.BytesIO(survey.data))
        meta = SurveyInput(survey.wheel_load_n, survey.band_min_m, survey.band_max_m)
        grid, level = survey_level_on_grid(raw["chainage_m"], raw["level_mm"], meta)
        al = align_to_track(session, track_id, grid, level)
        survey.chainage_offset_m = al.offset_m
        survey.alignment_status = al.status
        survey.alignment_correlation = al.correlation
        survey.alignment_reason = al.reason
        session.flush()
        _place(session, survey, grid, level)
    recompute_all(session, track_id)
    return surveys


def delete_survey(session: Session, survey: Survey) -> None:
    """Forget a survey and separate its stretch again without it (caller commits)."""
    lock_track(session, survey.track_id)
    t = SurveyLevels.__table__
    lo, hi = session.execute(
        select(func.min(t.c.chunk), func.max(t.c.chunk)).where(t.c.survey_id == survey.id)
    ).one()
    session.execute(delete(SurveyLevels).where(SurveyLevels.survey_id == survey.id))
    track_id = survey.track_id
    session.delete(survey)
    session.flush()
    if lo is not None:
        recompute_stiffness(session, track_id, int(lo), int(hi))


def list_surveys(session: Session, track_id: int) -> list[Survey]:
    """A track's surveys, oldest first."""
    return list(
        session.scalars(select(Survey).where(Survey.track_id == track_id).order_by(Survey.id))
    )


def get_survey(session: Session, track_id: int, survey_id: int) -> Survey:
    """One survey of a track; NotFound when there is none of that id on it."""
    survey = session.get(Survey, survey_id)
    if survey is None or survey.track_id != track_id:
        raise NotFound(f"survey {survey_id} not found on this track", field="survey_id")
    return survey
