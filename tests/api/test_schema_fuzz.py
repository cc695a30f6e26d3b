"""A bounded schema-driven fuzz run against a real server (issue 16, item 12): schemathesis
generates requests from the served OpenAPI document and checks the answers, in the default
configuration and with API keys required for reads and writes.

Bounded: a fixed seed, a few examples per operation, the examples and fuzzing phases (the
coverage phase's thousands of boundary cases are what the probe ran once; CI keeps the
quick ones), a time cap; all checks but ``positive_data_acceptance``: schema-valid requests
that the service refuses on rules a schema cannot state (a file that is no run log, limits
that must grow from alert to immediate, a vehicle name that does not exist, a name with
look-alike spaces) are 422 by design. Every other check runs: no 5xx, status codes, content
types, headers and bodies as documented, schema-violating requests refused, 405 with
``Allow``, security enforced where declared (``ignored_auth``).
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from api.live_server import LiveServer
from app.core.config import REPO_ROOT

SEED = 16
MAX_EXAMPLES = 6
MAX_TIME_S = 30
"""Cap of one run, s (fixed seed and examples: a run ends well before on a quiet machine)."""


def _schemathesis(url: str, report: Path, *headers: str) -> subprocess.CompletedProcess[str]:
    exe = Path(sys.executable).parent / "schemathesis"
    args = [
        str(exe), "run", f"{url}/openapi.json", "--checks", "all",
        "--exclude-checks", "positive_data_acceptance", "--max-examples", str(MAX_EXAMPLES),
        # one worker: hypothesis describes strategies with ast.parse, which is not thread-safe
        # on CPython 3.11 ("AST constructor recursion depth mismatch" with two workers)
        "--seed", str(SEED), "--workers", "1", "--phases", "examples,fuzzing", "--no-shrink",
        "--request-timeout", "60", "--max-response-time", "60", "--max-time", str(MAX_TIME_S),
        "--report", "junit", "--report-dir", str(report), "--output-truncate", "true",
    ]  # fmt: skip
    for h in headers:
        args += ["-H", h]
    env = {k: v for k, v in os.environ.items() if not k.startswith("SCHEMATHESIS_")}
    return subprocess.run(
        args, capture_output=True, text=True, timeout=MAX_TIME_S + 120, cwd=report, env=env
    )


def _create_key(settings) -> str:
    env = {k: v for k, v in os.environ.items() if not k.startswith("TRACKPROFILE_")}
    env |= {"DATABASE_URL": settings.sqlalchemy_url, "PYTHONPATH": str(REPO_ROOT)}
    out = subprocess.run(
        [sys.executable, "-m", "app", "create-key", "fuzzer"], capture_output=True, text=True,
        env=env, cwd=REPO_ROOT, check=True, timeout=120,
    )  # fmt: skip
    return out.stdout.strip().splitlines()[-1]


@pytest.mark.parametrize("keys", ["open", "keys required"])
def test_schemathesis_finds_nothing(settings, tmp_path, keys) -> None:
    env = {"TRACKPROFILE_SIMULATE_MAX_DURATION_S": "5"}  # simulations stay quick
    if keys == "keys required":
        env |= {"TRACKPROFILE_REQUIRE_API_KEY": "true",
                "TRACKPROFILE_REQUIRE_API_KEY_FOR_READS": "true"}  # fmt: skip
    server = LiveServer(settings, "fuzz", **env).start()
    try:
        headers = [f"X-API-Key: {_create_key(settings)}"] if keys == "keys required" else []
        result = _schemathesis(server.url, tmp_path, *headers)
    finally:
        server.stop()
    output = result.stdout + result.stderr
    assert "Tested:" in output, output[-3000:]
    assert result.returncode == 0, output[-6000:]
    assert "Traceback" not in server.log_text(), server.log_text()[-3000:]
