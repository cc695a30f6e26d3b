"""Helpers of the real-browser tests: the service in a subprocess, page watching, plot waits.

The app runs as a user starts it (``uvicorn app.main:app``) on a free loopback port with its own
SQLite file; the browser is Debian's ``/usr/bin/chromium`` launched by path (no
``playwright install``, nothing downloaded).
"""

from __future__ import annotations

import os
import socket
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import httpx

from support.samples import REPO

CHROMIUM = Path("/usr/bin/chromium")
CHROMIUM_ARGS = [
    "--no-sandbox",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
]
VIEWPORT = {"width": 1366, "height": 768}
SCREENSHOTS = REPO / "docs" / "screenshots"
SAMPLE_ZONES = ((140.0, 146.0), (333.0, 337.0))
"""Soft zones of sample_noisy (and of the generated stand-in), m."""
SAMPLE_START_M = 24.13

CHART_MARKS = """(() => {
  const painted = new Set();
  const tick = () => {
    for (const gd of document.querySelectorAll('.js-plotly-plot')) {
      if (gd.id && !painted.has(gd.id) && gd._fullLayout && gd.querySelector('.main-svg')) {
        painted.add(gd.id);
        // Marked in the first task after this frame: its layout and paint are done by then.
        const ch = new MessageChannel();
        ch.port1.onmessage = () => performance.mark('chart-painted:' + gd.id);
        ch.port2.postMessage(0);
      }
    }
    requestAnimationFrame(tick);
  };
  requestAnimationFrame(tick);
  let v;
  Object.defineProperty(window, 'Plotly', { configurable: true, get() { return v; }, set(x) {
    v = x;
    performance.mark('plotly-defined');
    for (const f of ['newPlot', 'react']) {
      const g = x[f];
      if (!g) continue;
      x[f] = function (...args) {
        if (!performance.getEntriesByName('first-draw').length) performance.mark('first-draw');
        return g.apply(this, args);
      };
    }
  } });
})();"""
"""An init script (``page.add_init_script``) timing a page's charts in the browser itself:
``chart-painted:<id>`` marks the end of the animation frame in which the chart with that
element id first has its SVG (the first task after the frame that lays it out and paints it:
a browser-measured first paint, free of the test driver's own delay in noticing it),
``plotly-defined`` when plotly.js has run, ``first-draw`` the first ``newPlot``/``react``
call."""


def painted_s(page: Any, chart_id: str) -> float:
    """Seconds from the navigation to the frame that first painted the chart ``chart_id``, as
    the browser measured it (``CHART_MARKS``, added to the page before the navigation): the
    figure the first-paint targets are about. A test driver's own wall clock also holds its
    delay in noticing the chart, 0.1-0.5 s when a long task (the next chart) follows the
    paint."""
    page.wait_for_function(
        "id => performance.getEntriesByName('chart-painted:' + id).length > 0", arg=chart_id
    )
    return float(
        page.evaluate(
            "id => performance.getEntriesByName('chart-painted:' + id)[0].startTime / 1000",
            chart_id,
        )
    )


def free_port() -> int:
    """A TCP port on 127.0.0.1 that nothing listens on right now."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@dataclass
class LiveServer:
    """A running service: its base URL, database URL and log file."""

    url: str
    database_url: str
    log_path: Path
    proc: subprocess.Popen[bytes]

    def api(self) -> httpx.Client:
        """An HTTP client of the service's API."""
        return httpx.Client(base_url=self.url, timeout=60.0)

    def log_tail(self, n: int = 4000) -> str:
        """The end of the server's log (for failure messages)."""
        try:
            return self.log_path.read_text(errors="replace")[-n:]
        except OSError:
            return ""


def start_server(
    data_dir: Path, database_url: str | None = None, settings: dict[str, str] | None = None
) -> LiveServer:
    """Start ``uvicorn app.main:app`` on a free port with a SQLite file under ``data_dir``.

    ``settings`` are extra ``TRACKPROFILE_*`` environment variables of the service.
    """
    port = free_port()
    db_url = database_url or f"sqlite:///{data_dir / 'trackprofile.db'}"
    env = {k: v for k, v in os.environ.items() if not k.startswith("TRACKPROFILE_")}
    env.update(
        {
            "DATABASE_URL": db_url,
            "TRACKPROFILE_DATA_DIR": str(data_dir),
            "PYTHONPATH": str(REPO),
        }
    )
    env.update(settings or {})
    log_path = data_dir / "server.log"
    log = log_path.open("wb")
    proc = subprocess.Popen(
        [sys.executable, "-m", "uvicorn", "app.main:app", "--host", "127.0.0.1",
         "--port", str(port), "--log-level", "warning", "--no-server-header"],
        cwd=REPO, env=env, stdout=log, stderr=subprocess.STDOUT,
    )  # fmt: skip
    server = LiveServer(f"http://127.0.0.1:{port}", db_url, log_path, proc)
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:
        if proc.poll() is not None:
            raise RuntimeError(f"the service exited at start:\n{server.log_tail()}")
        try:
            if httpx.get(f"{server.url}/healthz", timeout=2).status_code == 200:
                return server
        except httpx.HTTPError:
            pass
        time.sleep(0.2)
    stop_server(server)
    raise RuntimeError(f"the service did not answer /healthz within 60 s:\n{server.log_tail()}")


def stop_server(server: LiveServer) -> None:
    """Stop the service's process (terminate, then kill)."""
    server.proc.terminate()
    try:
        server.proc.wait(timeout=15)
    except subprocess.TimeoutExpired:
        server.proc.kill()
        server.proc.wait(timeout=5)


@dataclass
class PageWatch:
    """What a page did that a test may want to forbid: script errors, dialogs, 5xx answers."""

    page_errors: list[str] = field(default_factory=list)
    dialogs: list[str] = field(default_factory=list)
    server_errors: list[str] = field(default_factory=list)

    def assert_clean(self) -> None:
        """No uncaught script error, no alert/confirm/prompt, no 5xx answer."""
        assert not self.page_errors, f"script errors on the page: {self.page_errors}"
        assert not self.dialogs, f"dialogs opened: {self.dialogs}"
        assert not self.server_errors, f"5xx answers: {self.server_errors}"


def wait_for_plot(page: Any, selector: str, min_traces: int = 1) -> None:
    """Wait until the Plotly graph at ``selector`` has drawn at least ``min_traces`` traces."""
    page.wait_for_function(
        """([sel, n]) => {
            const gd = document.querySelector(sel);
            return !!(gd && gd.data && gd.data.length >= n && gd._fullLayout
                      && gd.querySelector('.main-svg'));
        }""",
        arg=[selector, min_traces],
    )


AXE_VERSION = "4.14.1"
AXE_PREFIX = REPO / ".cache" / "npm"
AXE_JS = AXE_PREFIX / "node_modules" / "axe-core" / "axe.min.js"


def axe_source() -> str:
    """axe-core's browser script, installed from npm by scripts/test.sh (and here, the first
    time, when a test runs without it)."""
    if not AXE_JS.exists():
        subprocess.run(
            ["npm", "install", "--no-save", "--no-audit", "--no-fund", "--no-package-lock",
             "--prefix", str(AXE_PREFIX), f"axe-core@{AXE_VERSION}"],
            check=True, capture_output=True, timeout=300,
        )  # fmt: skip
    return AXE_JS.read_text()


def ensure_plotly_bundle() -> None:
    """The dashboard's plotly.js bundle (or plotly's partial bundle when it cannot be built) at
    the plotly package's plotly.js version, which the service serves when present: made by
    scripts/_plotly.sh, run by scripts/test.sh (and here, when a test session starts without
    it; the script does nothing when it is there)."""
    env = {**os.environ, "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}"}
    subprocess.run(
        ["bash", "-c", ". scripts/_plotly.sh"], cwd=REPO, env=env, check=True, timeout=600
    )


def axe_violations(
    page: Any, source: str, impacts: tuple[str, ...] = ("serious", "critical")
) -> list[str]:
    """Run axe-core on the page as it is; the violations of the given impacts, one line each
    (rule, impact, the first offending elements)."""
    if not page.evaluate("() => typeof window.axe !== 'undefined'"):
        page.evaluate(source)  # evaluated by the browser itself: not subject to the page's CSP
    result = page.evaluate(
        """async () => {
            const r = await axe.run(document, { resultTypes: ['violations'] });
            return r.violations.map(v => ({ id: v.id, impact: v.impact,
                nodes: v.nodes.slice(0, 3).map(n => n.target.join(' ')) }));
        }"""
    )
    return [
        f"{v['id']} ({v['impact']}): {', '.join(v['nodes'])}"
        for v in result
        if v["impact"] in impacts
    ]
