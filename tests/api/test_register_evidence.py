"""The register's one defect record carries its evidence: on the public geometry set (two
coach and two heavy passes over rough rail, uploaded as the README says) no single pass can
tell a soft support from the rail's geometry, the separation can — and the register says so.

Each test names what it checks; the truth is the set's own ``*.truth.json``.
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from datetime import UTC, datetime, timedelta
from pathlib import Path
from typing import Any

import pytest
from starlette.testclient import TestClient

from app.main import create_app
from support.app_fixtures import make_settings

from .api_support import upload

pytestmark = pytest.mark.slow

DATA = Path("/work/shared/data/geometry")
PRESET = {"A": "table1", "B": "heavy"}
"""The truth's vehicle key and the preset it matches (same parameters)."""
T0 = datetime(2026, 5, 4, 7, 0, tzinfo=UTC)
TRACK = "geometry set"


@pytest.fixture(scope="module")
def geo(tmp_path_factory: pytest.TempPathFactory) -> Iterator[dict[str, Any]]:
    """The four runs uploaded one by one (a day apart), with their truth."""
    if not DATA.is_dir():
        pytest.skip("the public geometry set is not on this machine")
    names = ("geo_coach_1", "geo_heavy_1", "geo_coach_2", "geo_heavy_2")
    truths = [json.loads((DATA / f"{n}.truth.json").read_text()) for n in names]
    with TestClient(create_app(make_settings(tmp_path_factory.mktemp("evidence")))) as c:
        runs = []
        for i, (name, truth) in enumerate(zip(names, truths, strict=True)):
            r = upload(
                c, (DATA / f"{name}.csv").read_bytes(), f"{name}.csv", track=TRACK,
                vehicle=PRESET[truth["vehicle_key"]],
                start_chainage_m=truth["start_chainage_m"],
                recorded_at=(T0 + timedelta(days=i)).isoformat(),
            )  # fmt: skip
            assert r.status_code == 201, r.text
            runs.append(r.json())
        yield {"client": c, "runs": runs, "truth": truths[0]}


def test_separated_zones_are_confirmed_defects_with_depth_and_evidence(
    geo: dict[str, Any],
) -> None:
    """Every true zone is one defect from the separation: depth > 0 mm at the reference
    load, its loss within 10 points of the truth inside its band, 'separated: 4 passes,
    2 loads', status confirmed, first seen the earliest pass; no message of doubt."""
    c = geo["client"]
    truth = geo["truth"]
    frame = truth["start_chainage_m"] - truth["true_start_chainage_m"]
    defects = c.get(f"/api/v1/tracks/{TRACK}/defects").json()
    for zone in truth["zones"]:
        lo, hi = zone["start_m"] + frame, zone["end_m"] + frame
        over = [d for d in defects if d["start_m"] <= hi and d["end_m"] >= lo]
        assert len(over) == 1, (zone, over)
        d = over[0]
        assert d["source"] == "separated" and d["stiffness_basis"] == "separated", d
        assert d["depth_mm"] > 0, d
        assert abs(d["stiffness_loss_pct"] - 100 * zone["stiffness_loss"]) <= 10, d
        assert d["stiffness_loss_lo_pct"] <= d["stiffness_loss_pct"] <= d["stiffness_loss_hi_pct"]
        assert "separated: 4 passes, 2 loads" in d["evidence_text"], d
        assert d["status"] == "confirmed" and d["runs_seen"] == 4, d
        assert d["first_seen"].startswith(T0.date().isoformat()), d
        assert d["message"] is None, d
    sep = [d for d in defects if d["source"] == "separated"]
    assert len(sep) == len(truth["zones"]), sep


def test_csv_report_and_chainage_map_read_the_same_record(geo: dict[str, Any]) -> None:
    """The CSV carries the evidence line, the report names it beside each zone, and the
    chainage map's zones over the three soft spots are the separated ones (not '0 soft
    spots' because no single run detected them)."""
    c = geo["client"]
    zones = c.get(f"/api/v1/views/tracks/{TRACK}/chainage-map").json()["zones"]
    sep = [z for z in zones if z["source"] == "separated"]
    assert len(sep) == 3 and all(z["depth_mm"] > 0 for z in sep), zones
    assert all(z["evidence_text"].startswith("separated: 4 passes, 2 loads") for z in sep)
    csv = c.get(f"/api/v1/tracks/{TRACK}/defects.csv").text
    assert csv.count("separated: 4 passes, 2 loads") == 3, csv
    html = c.get(f"/api/v1/tracks/{TRACK}/report").text
    assert html.count("separated: 4 passes, 2 loads") >= 3


def test_not_separable_names_its_stretches_and_none_where_the_zones_lie(
    geo: dict[str, Any],
) -> None:
    """The stiffness answer says where it is not separable (km+m stretches, with the reason
    and what would help) and names no stretch over a true zone: there the separation holds."""
    c = geo["client"]
    truth = geo["truth"]
    frame = truth["start_chainage_m"] - truth["true_start_chainage_m"]
    st = c.get(f"/api/v1/tracks/{TRACK}/stiffness").json()
    for s in st["not_separable"]:
        assert s["reason"] in ("load", "precision")
        for zone in truth["zones"]:
            assert s["to_m"] < zone["start_m"] + frame or s["from_m"] > zone["end_m"] + frame, s
    if st["not_separable"]:
        first = st["not_separable"][0]
        assert st["message"].startswith("Geometry and stiffness are not separable at ")
        assert f"{int(first['from_m'] // 1000)}+" in st["message"]
    else:
        assert st["message"] is None
