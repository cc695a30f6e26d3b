"""The register's trend of a separated soft spot comes from the track's successive
separations (``app.services.track.separation_history``).

The separations are written by hand the way ``recompute_stiffness`` writes them (its soft
spots, then ``record_separation``) over stored runs of two wheel loads recorded a month
apart, so that each case of the history's rule is checked on its own: a new independent pair
of passes opens an entry, one more pass of a load already there (or the same passes separated
again) refines the latest, a deleted pass voids the entries it supported.
"""

from __future__ import annotations

from collections.abc import Iterator
from datetime import UTC, datetime, timedelta
from pathlib import Path
from typing import Any

import pytest
from sqlalchemy import delete, insert, select
from starlette.testclient import TestClient

from app.db.models import Run, TrackSeparationHistory, TrackStiffnessSpot, Vehicle
from app.db.session import Database
from app.main import create_app
from app.services.track.separation_history import record_separation
from support.app_fixtures import make_settings

T0 = datetime(2026, 1, 5, 7, 0, tzinfo=UTC)
LOADS = (50_000.0, 80_000.0)
"""The two wheel loads of the fleet, N (1.6 apart: distinct for the separation)."""


@pytest.fixture
def track(tmp_path: Path) -> Iterator[dict[str, Any]]:
    """A track with eight done runs, alternately light and heavy, one every 30 days."""
    settings = make_settings(tmp_path)
    with TestClient(create_app(settings)) as c:
        tid = c.post("/api/v1/tracks", json={"name": "history"}).json()["id"]
        db = Database(settings.database_url)
        with db.session() as s:
            vid = s.scalar(select(Vehicle.id).limit(1))
            ids = []
            for i in range(8):
                run = Run(
                    track_id=tid, vehicle_id=vid, source="upload", direction="increasing",
                    sample_rate_hz=1000.0, n_samples=1, duration_s=1.0, speed_min_mps=20.0,
                    speed_max_mps=20.0, status="done", content_hash=f"h{i}",
                    recorded_at=T0 + timedelta(days=30 * i), static_wheel_load_n=LOADS[i % 2],
                    chainage_min_m=0.0, chainage_max_m=500.0, alignment_status="aligned",
                )  # fmt: skip
                s.add(run)
                s.flush()
                ids.append(run.id)
            s.commit()
        yield {"client": c, "db": db, "id": tid, "runs": ids}


def separate(t: dict[str, Any], runs: list[int], loss: float, depth: float) -> None:
    """One separation of a spot at 200-206 m over ``runs``, stored as the separation does."""
    spot = {
        "track_id": t["id"], "start_m": 200.0, "end_m": 206.0, "peak_m": 203.0,
        "loss_pct": loss, "loss_lo_pct": loss - 5, "loss_hi_pct": loss + 5, "confidence": 0.9,
        "depth_mm": depth,
        "support": [{"kind": "run", "id": t["runs"][i], "force_n": LOADS[i % 2]} for i in runs],
    }  # fmt: skip
    with t["db"].session() as s:
        s.execute(delete(TrackStiffnessSpot).where(TrackStiffnessSpot.track_id == t["id"]))
        s.execute(insert(TrackStiffnessSpot), [spot])
        record_separation(s, t["id"], [spot])
        s.commit()


def entries(t: dict[str, Any]) -> int:
    with t["db"].session() as s:
        return len(s.scalars(select(TrackSeparationHistory.id)).all())


def defect(t: dict[str, Any]) -> dict[str, Any]:
    got = t["client"].get(f"/api/v1/tracks/{t['id']}/defects?include=history").json()
    assert len(got) == 1, got
    return dict(got[0])


def test_only_an_independent_pair_of_passes_opens_an_entry(track: dict[str, Any]) -> None:
    """Passes 0-1 (two loads) open the first entry; pass 2 (a light one: no new pair) and the
    same passes separated again (a vehicle edit) refine it; passes 2-3 (a new light and heavy
    pair) open the second, dated at pass 3."""
    separate(track, [0, 1], 40.0, 0.20)
    assert entries(track) == 1
    separate(track, [0, 1, 2], 41.0, 0.21)
    separate(track, [0, 1, 2], 41.5, 0.21)
    assert entries(track) == 1
    d = defect(track)
    assert d["status"] == "confirmed" and d["stiffness_loss_pct"] == 41.5, d
    separate(track, [0, 1, 2, 3], 42.0, 0.22)
    assert entries(track) == 2
    d = defect(track)
    seen = [h["recorded_at"][:10] for h in d["history"] if h["source"] == "separated"]
    assert seen == [str((T0 + timedelta(days=30)).date()), str((T0 + timedelta(days=90)).date())]
    # two separations: confirmed, not yet enough for a trend to decide
    assert d["status"] == "confirmed" and d["first_seen"].startswith(str(T0.date())), d
    assert d["depth_mm"] == pytest.approx(0.22) and d["stiffness_loss_pct"] == 42.0


def test_a_spot_softening_across_separations_is_worsening(track: dict[str, Any]) -> None:
    """Four pairs of passes, each separation finding the support softer (40 -> 55 % loss,
    0.20 -> 0.35 mm): the register's defect is worsening with a positive trend of the depth
    and of the loss, first seen on the first pass; a deleted pass voids the separations that
    rested on it."""
    for k in range(4):
        separate(track, list(range(2 * k + 2)), 40.0 + 5 * k, 0.20 + 0.05 * k)
    assert entries(track) == 4
    d = defect(track)
    assert d["status"] == "worsening", d
    assert d["trend_mm_per_month"] > 0.01 and d["trend_loss_pct_per_month"] > 1.0, d
    assert d["first_seen"].startswith(str(T0.date())), d
    assert len([h for h in d["history"] if h["source"] == "separated"]) == 4
    with track["db"].session() as s:
        s.execute(delete(Run).where(Run.id == track["runs"][3]))
        s.commit()
    # the second and third separations rested on it (the fourth is the current spot, which
    # the separation redoes without it): the first and the current are left, too few to trend
    d = defect(track)
    assert len([h for h in d["history"] if h["source"] == "separated"]) == 2, d["history"]
    assert d["status"] == "confirmed", d


def test_without_history_the_current_spot_stands_alone(track: dict[str, Any]) -> None:
    """A spot stored before the history existed (no entry) is one sighting, dated when its
    passes first spanned two loads: confirmed, as before."""
    separate(track, [0, 1, 2, 3], 45.0, 0.25)
    with track["db"].session() as s:
        s.execute(delete(TrackSeparationHistory))
        s.commit()
    d = defect(track)
    assert d["status"] == "confirmed", d
    assert [h["recorded_at"][:10] for h in d["history"]] == [str((T0 + timedelta(days=30)).date())]
