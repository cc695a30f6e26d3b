"""Every setting an operator can give is in the README's configuration table, under the
environment variable it is read from (a setting added without a row there fails here)."""

from __future__ import annotations

from pydantic import AliasChoices

from app.core.config import Settings
from support.samples import REPO

# Paths the package itself locates, and a start-up knob only test processes turn off.
NOT_FOR_OPERATORS = {
    "static_dir",
    "plotly_dashboard_js",
    "plotly_partial_js",
    "freeze_startup_heap",
}


def _env_name(name: str) -> str:
    field = Settings.model_fields[name]
    alias = field.validation_alias
    if isinstance(alias, AliasChoices):
        return str(alias.choices[0])
    if isinstance(alias, str):
        return alias
    return f"{Settings.model_config['env_prefix']}{name}".upper()


def _configuration_rows() -> set[str]:
    text = (REPO / "README.md").read_text(encoding="utf-8")
    section = text.split("\n## Configuration\n", 1)[1].split("\n## ", 1)[0]
    return {
        line.split("|")[1].strip().strip("`")
        for line in section.splitlines()
        if line.startswith("| `")
    }


def test_every_operator_setting_has_a_readme_row() -> None:
    rows = _configuration_rows()
    assert "DATABASE_URL" in rows  # the table was found and read
    missing = [
        _env_name(n)
        for n in Settings.model_fields
        if n not in NOT_FOR_OPERATORS and _env_name(n) not in rows
    ]
    assert not missing, f"README's configuration table lacks {missing}"


def test_the_readme_names_no_setting_that_does_not_exist() -> None:
    known = {_env_name(n) for n in Settings.model_fields}
    unknown = sorted(_configuration_rows() - known)
    assert not unknown, f"README documents settings app.core.config does not have: {unknown}"
