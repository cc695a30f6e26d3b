"""The service as a real process: ``uvicorn app.main:app`` on 127.0.0.1, for the tests that kill
it, load it from many threads, or run several instances on one database.

Every server is bound to the loopback interface on a free port the system chooses (a
launch that loses its port to another process is retried on another), runs against the
test's database (``DATABASE_URL``), and is stopped (or killed)
by the test. The worker's log (``app`` loggers at INFO) goes to a file per process, so a test
can count which process claimed which run.
"""

from __future__ import annotations

import json
import os
import re
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import httpx

from app.core.config import REPO_ROOT, Settings

LOG_CONFIG = {
    "version": 1,
    "disable_existing_loggers": False,
    "formatters": {
        "plain": {"format": "%(asctime)s %(process)d %(name)s %(levelname)s %(message)s"}
    },
    "handlers": {"err": {"class": "logging.StreamHandler", "formatter": "plain"}},
    "loggers": {
        "app": {"handlers": ["err"], "level": "INFO", "propagate": False},
        "uvicorn.error": {"handlers": ["err"], "level": "WARNING", "propagate": False},
    },
}

CLAIM_LINE = re.compile(r"claimed run (\d+) \(attempt (\d+)\)")
"""The worker's log line for a claim (see app.services.run_lifecycle.jobs.process)."""


_reserved: set[int] = set()
"""Ports given to servers of this test process that may not be listening yet."""

BIND_RETRIES = 5
"""Launches tried when the port was taken between choosing it and binding it."""


def free_port() -> int:
    """A free loopback port chosen by the system (an ephemeral one), not given out before.

    Nobody can hold a port for the server between this choice and its bind, so another
    process may take it meanwhile: :meth:`LiveServer.wait_healthy` then launches again on
    another port (the server's log says "address already in use").
    """
    while True:
        with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
            s.bind(("127.0.0.1", 0))
            port = int(s.getsockname()[1])
        if port not in _reserved:
            _reserved.add(port)
            return port


class LiveServer:
    """One uvicorn process serving the app on ``settings``' database.

    Parameters
    ----------
    settings : Settings
        The test's settings: its database URL and data directory are used.
    name : str
        Tells the processes of one test apart (log file name).
    env : dict
        More environment variables, e.g. ``{"TRACKPROFILE_INLINE_MAX_SAMPLES": "1000"}``.
    """

    def __init__(self, settings: Settings, name: str = "server", **env: Any) -> None:
        self.settings = settings
        self.name = name
        self.env = {k: str(v) for k, v in env.items()}
        self.port: int | None = None
        self.proc: subprocess.Popen[bytes] | None = None
        self._log_start = 0
        self.log_path = Path(settings.data_dir) / f"{name}.log"
        self._log_config = Path(settings.data_dir) / "log-config.json"

    @property
    def url(self) -> str:
        """Base URL, e.g. ``http://127.0.0.1:8041``."""
        return f"http://127.0.0.1:{self.port}"

    def start(self, timeout: float = 90.0) -> LiveServer:
        """Start the process and wait until ``/healthz`` answers 200."""
        self.launch()
        return self.wait_healthy(timeout)

    def launch(self) -> None:
        """Start the process (without waiting for it)."""
        self._log_config.write_text(json.dumps(LOG_CONFIG))
        env = {
            k: v
            for k, v in os.environ.items()
            if not k.startswith("TRACKPROFILE_") and k != "DATABASE_URL"
        }
        env |= {
            "DATABASE_URL": self.settings.sqlalchemy_url,
            "TRACKPROFILE_DATA_DIR": str(self.settings.data_dir),
            "TRACKPROFILE_POLL_INTERVAL_S": "0.05",
            "PYTHONPATH": str(REPO_ROOT),
            **self.env,
        }
        self.port = free_port()
        self._log_start = self.log_path.stat().st_size if self.log_path.exists() else 0
        log = open(self.log_path, "ab")  # noqa: SIM115 - the child process writes to it
        self.proc = subprocess.Popen(
            [
                sys.executable, "-m", "uvicorn", "app.main:app", "--host", "127.0.0.1",
                "--port", str(self.port), "--log-config", str(self._log_config),
                "--no-access-log", "--timeout-graceful-shutdown", "5", "--http", "h11",
                "--no-server-header",
            ],
            cwd=REPO_ROOT,
            env=env,
            stdout=log,
            stderr=subprocess.STDOUT,
        )  # fmt: skip
        log.close()

    def wait_healthy(self, timeout: float = 90.0) -> LiveServer:
        """Wait until ``/healthz`` answers 200 (the app started and migrated)."""
        assert self.proc is not None, "launch() first"
        deadline = time.monotonic() + timeout
        retries = BIND_RETRIES
        while time.monotonic() < deadline:
            if self.proc.poll() is not None:
                if retries and "address already in use" in self._log_since_launch().lower():
                    retries -= 1
                    _reserved.discard(self.port or 0)
                    self.launch()  # the port was taken meanwhile: another one
                    continue
                raise RuntimeError(f"{self.name} exited at start:\n{self.log_text()}")
            try:
                healthy = httpx.get(self.url + "/healthz", timeout=2).status_code == 200
                if healthy and self.proc.poll() is None:
                    return self
            except httpx.HTTPError:
                pass
            time.sleep(0.1)
        self.kill()
        raise RuntimeError(f"{self.name} did not become healthy:\n{self.log_text()}")

    def kill(self) -> None:
        """SIGKILL: the process dies at once, in whatever it was doing."""
        if self.proc is not None and self.proc.poll() is None:
            self.proc.send_signal(signal.SIGKILL)
            self.proc.wait(10)
        _reserved.discard(self.port or 0)

    def stop(self, timeout: float = 30.0) -> None:
        """SIGTERM (uvicorn's graceful shutdown), SIGKILL after ``timeout`` s."""
        if self.proc is not None and self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
            try:
                self.proc.wait(timeout)
            except subprocess.TimeoutExpired:
                self.kill()
        _reserved.discard(self.port or 0)

    def _log_since_launch(self) -> str:
        with open(self.log_path, "rb") as f:
            f.seek(self._log_start)
            return f.read().decode(errors="replace")

    def log_text(self) -> str:
        """Everything the process wrote (log lines, tracebacks)."""
        return self.log_path.read_text(errors="replace") if self.log_path.exists() else ""

    def claims(self) -> list[tuple[int, int]]:
        """``(run_id, attempt)`` of every claim this process's worker logged."""
        return [(int(m[1]), int(m[2])) for m in CLAIM_LINE.finditer(self.log_text())]


@contextmanager
def live_servers(settings: Settings, count: int = 1, **env: Any) -> Iterator[list[LiveServer]]:
    """``count`` servers on the test's database, stopped on exit (killed if they hang)."""
    servers = [LiveServer(settings, f"server{i}", **env) for i in range(count)]
    try:
        for s in servers:  # launched together: they start (and migrate) at the same time
            s.launch()
        for s in servers:
            s.wait_healthy()
        yield servers
    finally:
        for s in servers:
            s.stop()


def wait_status(
    client: httpx.Client, run_id: int, until: set[str], timeout: float = 120.0
) -> dict[str, Any]:
    """Poll ``GET /api/v1/runs/{id}`` until its status is in ``until``; the last answer."""
    deadline = time.monotonic() + timeout
    while True:
        run = client.get(f"/api/v1/runs/{run_id}").json()
        if run.get("status") in until or time.monotonic() > deadline:
            return run
        time.sleep(0.05)
