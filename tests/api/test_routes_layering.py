"""Routes parse, call a service and serialise: no SQL in ``app/api/routes/``.

A static check of the route modules' syntax trees (no HTTP): the database is reached through
``app/services/`` only, so that a rule about stored data has one home.
"""

from __future__ import annotations

import ast
from pathlib import Path

import app.db.models as models
from app.core.config import REPO_ROOT

ROUTES = REPO_ROOT / "app" / "api" / "routes"

SESSION_SQL = {
    "execute", "scalar", "scalars", "query", "get", "add", "add_all", "delete", "merge",
    "flush", "refresh",
}  # fmt: skip
"""Session methods that read or write rows; a route may only ``commit`` (its transaction)."""

STATEMENTS = {"select", "insert", "update", "delete", "text"}

MODEL_NAMES = {n for n, v in vars(models).items() if hasattr(v, "__table__")}


def _name(node: ast.expr) -> str:
    if isinstance(node, ast.Name):
        return node.id
    return node.attr if isinstance(node, ast.Attribute) else ""


def _sql_call(node: ast.Call) -> str | None:
    func = node.func
    if isinstance(func, ast.Name):
        return f"{func.id}(...)" if func.id in STATEMENTS else None
    if not isinstance(func, ast.Attribute) or func.attr not in SESSION_SQL:
        return None
    receiver = _name(func.value)
    model = _name(node.args[0]) if node.args else ""
    # a session by its name, or any object asked for a model's rows (``db.get(Track, 3)``)
    if "session" in receiver.lower() or receiver == "s" or model in MODEL_NAMES:
        return f"{receiver}.{func.attr}(...)"
    return None


def sql_in(source: str) -> list[str]:
    """Where ``source`` (a module's text) reaches the database itself: ``line: what``."""
    found = []
    for node in ast.walk(ast.parse(source)):
        what = None
        if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("sqlalchemy"):
            names = [a.name for a in node.names]
            if names != ["Session"]:  # the type of a service's argument, not SQL
                what = f"from {node.module} import {', '.join(names)}"
        elif isinstance(node, ast.Import):
            what = ", ".join(a.name for a in node.names if a.name.startswith("sqlalchemy"))
        elif isinstance(node, ast.Call):
            what = _sql_call(node)
        if what:
            found.append((node.lineno, what))
    return [f"{line}: {what}" for line, what in sorted(found)]


def test_the_check_finds_sql() -> None:
    """The check itself: each way a route could reach the database is found."""
    source = (
        "from sqlalchemy import func, select\n"
        "import sqlalchemy\n"
        "def route(session, s, db):\n"
        "    session.scalar(select(func.count()))\n"
        "    s.execute('SELECT 1')\n"
        "    db.get(Track, 3)\n"
        "    session.get(Run, 1)\n"
        "    session.add(object())\n"
        "    form = {}; form.get('file')\n"  # not SQL
    )
    found = sql_in(source)
    assert [f.split(":")[0] for f in found] == ["1", "2", "4", "4", "5", "6", "7", "8"], found


def test_no_sql_in_routes() -> None:
    """No route module imports SQLAlchemy's statements or calls a session's SQL methods:
    a query belongs in a function of ``app/services/``."""
    modules = sorted(ROUTES.glob("*.py"))
    assert len(modules) > 5  # the routes are where this test thinks they are
    offences = {
        str(p.relative_to(REPO_ROOT)): found
        for p in modules
        if (found := sql_in(Path(p).read_text(encoding="utf-8")))
    }
    assert not offences, f"SQL in routes (move it into app/services/): {offences}"


SCHEMAS_READING_SERVICES = {"app/schemas/track_intel.py": {"app.services.track.aggregate"}}
"""Left to move: the aggregate's pass count, stated in a schema's description."""


def test_schemas_import_no_service() -> None:
    """Schemas describe requests and answers: they import no service (the services take plain
    arguments; ``app/api/convert.py`` goes between), beyond the one import left listed."""
    found: dict[str, set[str]] = {}
    for p in sorted((REPO_ROOT / "app" / "schemas").glob("*.py")):
        tree = ast.parse(p.read_text(encoding="utf-8"))
        modules = {n.module or "" for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)}
        modules |= {a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names}
        services = {m for m in modules if m.startswith("app.services")}
        if services:
            found[str(p.relative_to(REPO_ROOT))] = services
    assert found == SCHEMAS_READING_SERVICES
