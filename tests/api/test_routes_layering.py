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

SQL_METHODS = {"execute", "scalar", "scalars", "query", "exec_driver_sql", "add", "add_all"}
"""Session methods that run or stage SQL (``session.delete`` is left to the services too, but
its name is shared with routes' HTTP verbs and is caught as ``session.delete`` below)."""

SESSION_ONLY = {"get", "delete", "merge", "flush", "refresh"}
"""Methods whose name other objects share (``dict.get``): SQL only on a session."""

MODEL_NAMES = {n for n, v in vars(models).items() if isinstance(v, type) and hasattr(v, "__table__")}


def _receiver(node: ast.expr) -> str:
    return node.id if isinstance(node, ast.Name) else (node.attr if isinstance(node, ast.Attribute) else "")


def sql_in(source: str) -> list[str]:
    """Where ``source`` (a module's text) reaches the database itself: ``line: what``."""
    found = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("sqlalchemy"):
            names = [a.name for a in node.names]
            if names != ["Session"]:  # the type of a service's argument, not SQL
                found.append(f"{node.lineno}: from {node.module} import {', '.join(names)}")
        elif isinstance(node, ast.Import):
            found += [f"{node.lineno}: import {a.name}" for a in node.names if a.name.startswith("sqlalchemy")]
        elif isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute):
            method, receiver = node.func.attr, _receiver(node.func.value)
            on_session = "session" in receiver.lower() or receiver == "s"
            if method in SQL_METHODS and on_session:
                found.append(f"{node.lineno}: {receiver}.{method}(...)")
            elif method in SESSION_ONLY and on_session:
                found.append(f"{node.lineno}: {receiver}.{method}(...)")
            elif method in SQL_METHODS | {"get"} and any(
                isinstance(a, ast.Name) and a.id in MODEL_NAMES for a in node.args[:1]
            ):
                found.append(f"{node.lineno}: {receiver}.{method}({node.args[0].id}, ...)")  # type: ignore[attr-defined]
        elif isinstance(node, ast.Call) and isinstance(node.func, ast.Name):
            if node.func.id in {"select", "insert", "update", "delete", "text"}:
                found.append(f"{node.lineno}: {node.func.id}(...)")
    return sorted(found, key=lambda f: int(f.split(":")[0]))


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
