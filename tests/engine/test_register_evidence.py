"""The register's evidence model: sightings of different kinds at one place are one defect
that says which kinds support it, how many passes and how many distinct wheel loads."""

from __future__ import annotations

from datetime import UTC, datetime, timedelta

import pytest

from engine.errors import ParameterError
from engine.register import Observation, Support, build_register, complete_at, count_loads

T0 = datetime(2026, 1, 1, tzinfo=UTC)


def _pass(run: int, day: int, load: float) -> Support:
    return Support(run, T0 + timedelta(days=day), load)


def test_count_loads_groups_loads_ten_percent_apart() -> None:
    """80, 82 and 85 kN are one load; 120 and 125 kN another; unknown loads alone are one."""
    assert count_loads([80e3, 82e3, 85e3, 120e3, 125e3], 1.1) == 2
    assert count_loads([None, None], 1.1) == 1
    assert count_loads([], 1.1) == 0


def test_a_separated_spot_and_single_pass_dips_are_one_defect_with_both_kinds() -> None:
    """Two coach and two heavy passes separate a spot; one coach pass also saw a dip there:
    one defect, figures from the separation, 4 passes and 2 loads, confirmed, first seen at
    the earliest pass, dated (for its level) when the second load arrived."""
    passes = (_pass(1, 0, 80e3), _pass(2, 3, 80e3), _pass(3, 5, 120e3), _pass(4, 9, 121e3))
    sep = Observation(
        1, complete_at(passes, 1.1), 120.0, 126.0, 123.0, 0.28, 46.0, source="separated",
        support=passes, loss_lo_pct=40.0, loss_hi_pct=51.0,
    )  # fmt: skip
    dip = Observation(
        2, passes[1].recorded_at, 121.0, 125.0, 123.5, 0.9, None, support=(passes[1],)
    )
    (d,) = build_register([dip, sep])
    assert d.source == "separated" and d.depth_mm == pytest.approx(0.28)
    assert d.stiffness_loss_pct == 46.0 and d.stiffness_loss_lo_pct == 40.0
    assert d.evidence_text == "separated: 4 passes, 2 loads; single pass: 1 pass, 1 load"
    assert d.status == "confirmed" and d.runs_seen == 4
    assert d.first_seen == T0 and d.level_since == passes[2].recorded_at


def test_one_pass_alone_is_new_and_an_unknown_source_is_refused() -> None:
    """A defect one pass supports is new; a sighting of an unregistered kind names its field."""
    (d,) = build_register([Observation(7, T0, 10.0, 12.0, 11.0, 0.3, None)])
    assert d.status == "new" and d.evidence_text == "single pass: 1 pass, 1 load"
    with pytest.raises(ParameterError) as err:
        Observation(7, T0, 10.0, 12.0, 11.0, 0.3, None, source="guess")
    assert err.value.field == "source"
