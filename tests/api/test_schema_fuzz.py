"""A bounded schema-driven fuzz run against a real server on a seeded database: schemathesis
generates requests from the served OpenAPI document and checks the answers.

What runs: every check (``--checks all``: no 5xx, status codes, content types, headers and
bodies as documented, schema-violating requests refused, schema-valid requests accepted,
405 with ``Allow``, security enforced where declared), all four phases (examples, coverage,
fuzzing, stateful), in four configurations: open, read-only, keys required with a key of
the ``read`` scope only, and keys required with a key of every scope. The database is
seeded once (a track with simulated runs of two vehicles, a calibration, a centerline) and
each configuration gets its own copy, so that ids, names and calibrations are there to be
found and a configuration that deletes does not empty the next one's.

What is allowed: the one allow-list, ``tests/api/schemathesis.toml`` next to this file,
names each operation whose schema-valid requests may be refused (422) on a rule a schema
cannot state (a cross-field rule, a rule on stored data or on a file's content), with the
reason for each. Every other failure fails the test.

Bounded: a fixed seed, :data:`MAX_EXAMPLES` per operation in the examples and fuzzing
phases, :data:`STATEFUL_STEPS` per stateful scenario, simulations capped at a few seconds
of travel; the coverage phase is what the schema defines (boundary values of every
parameter, unexpected methods). ``scripts/fuzz.sh`` runs the same harness longer in six
configurations, with more examples (docs/fuzzing.md).
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import time
import tomllib
import warnings
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest

from api.live_server import LiveServer
from app.core.config import Settings
from app.core.security import generate_key, hash_key, key_prefix
from app.db.models import ApiKey
from app.db.session import Database
from app.main import create_app
from support.app_fixtures import make_settings

with warnings.catch_warnings():
    warnings.simplefilter("ignore")
    from starlette.testclient import TestClient

SEED = int(os.environ.get("FUZZ_SEED", "28"))
MAX_EXAMPLES = int(os.environ.get("FUZZ_MAX_EXAMPLES", "2"))
"""Cases per operation in the examples and fuzzing phases (``FUZZ_MAX_EXAMPLES``)."""
STATEFUL_STEPS = int(os.environ.get("FUZZ_STATEFUL_STEPS", "3"))
"""Most calls in one stateful scenario (``FUZZ_STATEFUL_STEPS``)."""
ALLOW_LIST = Path(__file__).with_name("schemathesis.toml")
"""The documented allow-list (and the other settings every run shares)."""
SIMULATE_MAX_S = 2
"""Longest simulated run the fuzzed server accepts, s of travel (a simulation is the most
expensive request a client can make; the seeded runs are longer)."""

CONFIGURATIONS: dict[str, dict[str, Any]] = {
    "open": {"env": {}},
    "read-only": {"env": {"TRACKPROFILE_READ_ONLY": "true"}},
    "keys, no key": {"env": {"TRACKPROFILE_REQUIRE_API_KEY_FOR_READS": "true"}, "key": None},
    "read scope": {"env": {"TRACKPROFILE_REQUIRE_API_KEY_FOR_READS": "true"}, "key": "read"},
    "write scope": {
        "env": {"TRACKPROFILE_REQUIRE_API_KEY_FOR_READS": "true"},
        "key": "read write",
    },
    "full key": {
        "env": {"TRACKPROFILE_REQUIRE_API_KEY_FOR_READS": "true"},
        "key": "read write admin",
    },
}
"""Every configuration the fuzzer knows; the test command runs :data:`IN_TESTS`, the longer
run of ``scripts/fuzz.sh`` all six (``FUZZ_CONFIGURATIONS=all``)."""
IN_TESTS = (
    tuple(CONFIGURATIONS)
    if os.environ.get("FUZZ_CONFIGURATIONS") == "all"
    else ("open", "read-only", "read scope", "full key")
)

PENDING: dict[str, str] = {}
"""Server tracebacks the fuzzer provokes that are known and being fixed elsewhere, by a
frame they contain. Nothing else may appear in the server's log."""


def seed_database(directory: Path) -> Path:
    """A database with what the API's operations address: track ``fuzz line`` with five
    simulated runs (vehicles ``table1`` and ``fuzz car``), a finished calibration of
    ``fuzz car`` and a centerline. Returns the SQLite file."""
    settings = make_settings(directory, simulate_max_duration_s=20)
    with TestClient(create_app(settings)) as c:
        for i, (vehicle, speed) in enumerate(
            (("table1", 40), ("table1", 50), ("fuzz car", 40), ("fuzz car", 50))
        ):
            if i == 2:
                r = c.post("/api/v1/vehicles", json={"name": "fuzz car", "preset": "table1"})
                assert r.status_code == 201, r.text
            body = {"track": "fuzz line", "vehicle": vehicle, "length_m": 250,
                    "speed_mps": speed, "seed": i, "zones": ["140:146:0.5"]}  # fmt: skip
            r = c.post("/api/v1/simulate", json=body)
            assert r.status_code == 201, r.text
        line = {"type": "LineString", "coordinates": [[11.0, 48.0], [11.01, 48.0]]}
        r = c.put("/api/v1/tracks/fuzz line/centerline", json=line)
        assert r.status_code == 201, r.text
        r = c.post("/api/v1/vehicles/fuzz car/calibrate", json={"fit": ["Is"]})
        assert r.status_code == 202, r.text
        deadline = time.monotonic() + 120
        while c.get("/api/v1/vehicles/fuzz car/calibrations/1").json()["status"] == "running":
            assert time.monotonic() < deadline, "the seed calibration did not finish"
            time.sleep(0.1)
    return Path(settings.data_dir) / "trackprofile.db"


def add_key(settings: Settings, scopes: str) -> str:
    """A new API key with ``scopes`` in the database of ``settings``."""
    key = generate_key()
    db = Database(settings.sqlalchemy_url)
    try:
        with db.session() as s:
            s.add(ApiKey(name=f"fuzzer ({scopes})", prefix=key_prefix(key),
                         key_hash=hash_key(key), scopes=scopes))  # fmt: skip
            s.commit()
    finally:
        db.dispose()
    return key


def fuzz(
    seeded: Path,
    directory: Path,
    configuration: str,
    *,
    max_examples: int = MAX_EXAMPLES,
    stateful_steps: int = STATEFUL_STEPS,
) -> tuple[subprocess.CompletedProcess[str], str]:
    """Run schemathesis against a server of ``configuration`` on a copy of ``seeded``: its
    answer and the server's log."""
    conf = CONFIGURATIONS[configuration]
    directory.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(seeded, directory / "trackprofile.db")
    settings = make_settings(directory)
    headers = []
    if conf.get("key"):
        headers = ["-H", f"X-API-Key: {add_key(settings, conf['key'])}"]
    env = {"TRACKPROFILE_SIMULATE_MAX_DURATION_S": str(SIMULATE_MAX_S), **conf["env"]}
    server = LiveServer(settings, "fuzz", **env).start()
    try:
        # The document of the configuration, as its clients see it (read with a key of
        # every scope: the no-key configuration's clients are the ones being refused).
        key = add_key(settings, "read")
        doc = httpx.get(server.url + "/openapi.json", headers={"X-API-Key": key}, timeout=30)
        assert doc.status_code == 200, doc.text
        schema = directory / "openapi.json"
        schema.write_text(json.dumps(doc.json()))
        config = directory / "schemathesis.toml"
        config.write_text(
            f"{ALLOW_LIST.read_text()}\n[phases.stateful]\nmax-steps = {stateful_steps}\n"
        )
        args = [
            str(Path(sys.executable).parent / "schemathesis"), "--config-file", str(config),
            "run", str(schema), "--url", server.url, "--checks", "all",
            "--phases", "examples,coverage,fuzzing,stateful",
            "--max-examples", str(max_examples), "--seed", str(SEED), "--no-shrink",
            # one worker: hypothesis describes strategies with ast.parse, which is not
            # thread-safe on CPython 3.11 ("AST constructor recursion depth mismatch")
            "--workers", "1", "--request-timeout", "60", "--max-response-time", "60",
            "--report", "junit", "--report-dir", str(directory / "report"),
            "--output-truncate", "true", *headers,
        ]  # fmt: skip
        run_env = {k: v for k, v in os.environ.items() if not k.startswith("SCHEMATHESIS_")}
        result = subprocess.run(
            args, capture_output=True, text=True, timeout=1800, cwd=directory, env=run_env
        )
    finally:
        server.stop()
    return result, server.log_text()


@pytest.fixture(scope="module")
def seeded(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Path]:
    yield seed_database(tmp_path_factory.mktemp("seed"))


@pytest.mark.slow
@pytest.mark.sqlite_only
@pytest.mark.parametrize("configuration", IN_TESTS)
def test_schemathesis_finds_nothing_outside_the_allow_list(
    seeded: Path, tmp_path: Path, configuration: str
) -> None:
    result, log = fuzz(seeded, tmp_path, configuration)
    output = result.stdout + result.stderr
    assert "Tested:" in output, output[-3000:]
    assert result.returncode == 0, output[-8000:]
    tracebacks = [t for t in log.split("Traceback")[1:] if not any(p in t for p in PENDING)]
    assert not tracebacks, log[-3000:]


def test_the_allow_list_gives_a_reason_for_each_entry(settings: Settings) -> None:
    """Every entry of the allow-list says why (a ``# Reason:`` comment right above it),
    allows 422 and nothing else beyond schemathesis' defaults, and names operations the
    API has (an entry cannot outlive its operation unnoticed)."""
    parts = ALLOW_LIST.read_text().split("[[operations]]")
    assert len(parts) > 1, "the allow-list has no entries"
    paths = create_app(settings).openapi()["paths"]
    known = {f"{m.upper()} {p}" for p, item in paths.items() for m in item}
    defaults = {"2xx", "3xx", "401", "403", "404", "409", "429"}
    for before, entry in zip(parts, parts[1:], strict=False):
        body = entry.split("\n\n")[0]
        comment = []
        for line in reversed(before.rstrip().splitlines()):
            if not line.startswith("#"):
                break
            comment.insert(0, line)
        assert comment and comment[0].startswith("# Reason: "), entry
        config = tomllib.loads("[[operations]]" + body)["operations"][0]
        names = config["include-name"]
        names = [names] if isinstance(names, str) else names
        assert set(names) <= known, set(names) - known
        statuses = config["checks"]["positive_data_acceptance"]["expected-statuses"]
        assert set(statuses) == defaults | {"422"}, statuses
        assert set(config) == {"include-name", "checks"}, config
