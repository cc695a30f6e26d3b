"""Services without HTTP: they take plain arguments and raise domain errors, and the HTTP layer
(app.core.errors) alone turns those into status codes."""

from __future__ import annotations

from pathlib import Path

import pytest

from app.core.errors import DOMAIN_STATUS, domain_status
from app.db.migrate import upgrade
from app.db.session import Database
from app.services.context import AppContext
from app.services.errors import (
    Conflict,
    DomainError,
    Invalid,
    Malformed,
    NotFound,
    TooLarge,
    Unsupported,
)
from app.services.run_lifecycle.logs import parse_csv
from app.services.run_lifecycle.simulation import SimulationSpec, simulate_and_submit
from app.services.views.window import Window
from engine.errors import LogFormatError
from engine.sensor import SensorModel
from engine.track import SoftZone
from support.app_fixtures import database_url_for, make_settings


def _ctx(tmp_path: Path) -> AppContext:
    settings = make_settings(tmp_path, start_worker=False)
    db = Database(database_url_for(tmp_path))
    upgrade(db)
    return AppContext(settings=settings, db=db)


def test_status_codes_live_in_one_table() -> None:
    """Each domain error class has one status code; subclasses inherit their parent's."""
    classes = (NotFound, Conflict, Invalid, TooLarge, Unsupported, Malformed)
    assert {cls: DOMAIN_STATUS[cls] for cls in classes} == {
        NotFound: 404, Conflict: 409, Invalid: 422, TooLarge: 413, Unsupported: 415,
        Malformed: 400,
    }  # fmt: skip

    class Gone(NotFound):
        pass

    assert domain_status(Gone("x")) == 404


def test_simulation_without_room_is_invalid_and_stores_nothing(tmp_path: Path) -> None:
    """simulate_and_submit takes a plain spec and raises Invalid naming the field."""
    ctx = _ctx(tmp_path)
    spec = SimulationSpec(
        track="t", vehicle=None, name=None, length_m=100.0, speed_mps=20.0,
        zones=(SoftZone(40.0, 44.0, 0.5),), start_chainage_m=95.0, direction="increasing",
        sensor=SensorModel(), jitter=0.0, seed=0,
    )  # fmt: skip
    with pytest.raises(Invalid) as err:
        simulate_and_submit(ctx, spec)
    assert err.value.facts["field"] == "start_chainage_m"
    assert isinstance(err.value, DomainError) and "room to run" in err.value.message


def test_unreadable_csv_is_invalid_with_the_file_facts() -> None:
    """A log the engine refuses becomes Invalid carrying field, column, row and kind."""
    with pytest.raises(Invalid) as err:
        parse_csv(b"time_s,accel_z_mps2,pitch_rate_radps,speed_mps\n0,1,2,x\n", {})
    detail = err.value.detail()
    assert detail["field"] == "file" and detail["kind"] == LogFormatError.__name__
    assert "row" in detail or "column" in detail


def test_window_rule() -> None:
    """to_m before from_m is refused naming to_m; equal ends are a one-point window."""
    assert Window(5.0, 5.0).span_m == 0.0
    assert Window(None, 3.0).stored(1.0) == (None, 2.0)
    with pytest.raises(Invalid) as err:
        Window(5.0, 4.0)
    assert err.value.facts["field"] == "to_m"


def test_csv_options_are_derived_from_the_reader() -> None:
    """The upload schema, the preview's option list and the engine CLI's flags are the fields
    of engine.logio.CsvOptions, units included (chainage_unit among them)."""
    import dataclasses

    from app.schemas.runs import CsvOptionsFields
    from app.services.views.charts import PREVIEW_OPTION_NAMES
    from engine.cli import build_parser
    from engine.logio import OPTION_UNITS, CsvOptions

    names = [f.name for f in dataclasses.fields(CsvOptions)]
    assert list(CsvOptionsFields.model_fields) == names == list(PREVIEW_OPTION_NAMES)
    assert "chainage_unit" in names
    schema = CsvOptionsFields.model_json_schema()["properties"]
    for role, units in OPTION_UNITS.items():
        assert schema[f"{role}_unit"]["x-units"] == list(units)
    argv = ["process", "run.csv", "--out", "out", "--chainage-unit", "km"]
    flags = build_parser().parse_args(argv)
    assert flags.chainage_unit == "km"


def test_a_survey_over_the_upload_limit_is_too_large(tmp_path: Path) -> None:
    """import_survey refuses a file over the upload limit before reading it (TooLarge, 413)."""
    from app.services.track.surveys import SurveyInput, import_survey

    ctx = _ctx(tmp_path)
    limit = ctx.settings.max_upload_bytes
    with pytest.raises(TooLarge) as err:
        import_survey(ctx, "t", bytearray(limit + 1), SurveyInput(1e5, 3.0, 25.0))
    assert err.value.facts["limit_bytes"] == limit and "upload limit" in err.value.message
