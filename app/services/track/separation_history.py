"""The history of a track's separations: what each successive separation said of a soft spot.

The separation (``app.services.track.separation_store``) keeps only its newest soft spots; this
module keeps
the earlier results beside them, so that the register can trend a separated defect and date
its sightings (``app.services.track.register.separated_observations``). A separation opens a new
entry for a spot when the passes it adds to those the spot's latest entry opened with span two
wheel loads by themselves: an independent pair of passes, new evidence of the support's state.
Anything less (one more pass of a load already there, a reprocess after a vehicle edit, a
deleted pass) refines the latest entry: the same evidence, separated again.
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from sqlalchemy import insert, select, update
from sqlalchemy.orm import Session

from app.db.base import utcnow
from app.db.models import TrackSeparationHistory
from engine.register import RegisterConfig, count_loads
from engine.separation import SeparationConfig

LOAD_RATIO = SeparationConfig().min_load_ratio
"""Wheel loads this ratio apart count as distinct: the separation's own threshold."""

JOIN_GAP_M = RegisterConfig().join_gap_m
"""Extents closer than this are one soft spot: the register's own merging distance, m."""

SEARCH_M = 100.0
"""Reach of the search for a spot's entries around its extent, m (longer than any spot)."""

FIGURES = ("start_m", "end_m", "peak_m", "loss_pct", "depth_mm", "loss_lo_pct", "loss_hi_pct")
"""The figures of a separated spot an entry keeps (``TrackStiffnessSpot`` columns)."""

Key = tuple[str, int]


def pass_key(entry: Mapping[str, Any]) -> Key:
    """A support entry's pass (``{"kind", "id", ...}``) as ``(kind, id)``."""
    return str(entry["kind"]), int(entry["id"])


@dataclass(frozen=True)
class Entry:
    """One separation of a soft spot (aligned chainage m, loss %, depth mm at the reference
    load): the passes behind it (``support``, ``{"kind", "id", "force_n"}`` each) and the
    passes it opened with (``base``)."""

    start_m: float
    end_m: float
    peak_m: float
    loss_pct: float
    depth_mm: float | None
    loss_lo_pct: float | None
    loss_hi_pct: float | None
    support: tuple[Mapping[str, Any], ...]
    base: frozenset[Key]

    def overlaps(self, start_m: float, end_m: float) -> bool:
        """Whether this entry is of the spot over ``[start_m, end_m]`` (m)."""
        return _same_spot(self.start_m, self.end_m, start_m, end_m)


def _same_spot(a_start: float, a_end: float, b_start: float, b_end: float) -> bool:
    return a_start <= b_end + JOIN_GAP_M and b_start <= a_end + JOIN_GAP_M


def _opens(base: frozenset[Key], support: Sequence[Mapping[str, Any]]) -> bool:
    added = [e.get("force_n") for e in support if pass_key(e) not in base]
    return count_loads(added, LOAD_RATIO) >= 2


def record_separation(session: Session, track_id: int, spots: Sequence[Mapping[str, Any]]) -> None:
    """Add the soft spots a separation has just stored (``TrackStiffnessSpot`` columns with
    ``support``) to the track's history: each opens a new entry or refines its spot's latest
    (see the module's description). Caller's transaction."""
    if not spots:
        return
    lo = min(s["start_m"] for s in spots) - SEARCH_M
    hi = max(s["end_m"] for s in spots) + SEARCH_M
    history = read_history(session, track_id, lo, hi)
    added, refined = [], []
    now = utcnow()
    for spot in spots:
        support = list(spot["support"])
        figures = {k: spot[k] for k in FIGURES}
        latest = history.latest(spot["start_m"], spot["end_m"])
        if latest is not None and not _opens(latest[1].base, support):
            refined.append({"id": latest[0], **figures, "support": support, "separated_at": now})
            continue
        base = sorted([k, i] for k, i in {pass_key(e) for e in support})
        added.append({"track_id": track_id, **figures, "support": support, "base": base,
                      "separated_at": now})  # fmt: skip
    # ORM bulk statements: an UPDATE by primary key per refined entry, one INSERT for the new
    if refined:
        session.execute(update(TrackSeparationHistory), refined)
    if added:
        session.execute(insert(TrackSeparationHistory), added)


class TrackHistory:
    """A track's separation history, looked up by a spot's extent."""

    def __init__(self, entries: Sequence[tuple[int, Entry]]) -> None:
        self._by_peak = sorted(entries, key=lambda ie: ie[1].peak_m)
        self._peaks = [e.peak_m for _, e in self._by_peak]

    def _of(self, start_m: float, end_m: float) -> list[tuple[int, Entry]]:
        lo = bisect.bisect_left(self._peaks, start_m - SEARCH_M)
        hi = bisect.bisect_right(self._peaks, end_m + SEARCH_M)
        mine = [ie for ie in self._by_peak[lo:hi] if ie[1].overlaps(start_m, end_m)]
        return sorted(mine, key=lambda ie: ie[0])

    def of(self, start_m: float, end_m: float) -> list[Entry]:
        """The entries of the spot over ``[start_m, end_m]`` (m), oldest first."""
        return [e for _, e in self._of(start_m, end_m)]

    def latest(self, start_m: float, end_m: float) -> tuple[int, Entry] | None:
        """The newest entry of the spot over ``[start_m, end_m]`` (m) with its row id."""
        mine = self._of(start_m, end_m)
        return mine[-1] if mine else None


def read_history(
    session: Session, track_id: int, from_m: float = -math.inf, to_m: float = math.inf
) -> TrackHistory:
    """The track's separation history (the entries peaking within ``[from_m, to_m]``, m)."""
    h = TrackSeparationHistory.__table__
    where = [h.c.track_id == track_id]
    if math.isfinite(from_m):
        where.append(h.c.peak_m >= from_m)
    if math.isfinite(to_m):
        where.append(h.c.peak_m <= to_m)
    rows = session.execute(
        select(h.c.id, *(h.c[k] for k in FIGURES), h.c.support, h.c.base).where(*where)
    )
    return TrackHistory([
        (r[0], Entry(*r[1:8], tuple(r[8]), frozenset((str(k), int(i)) for k, i in r[9])))
        for r in rows
    ])  # fmt: skip
