"""plotly.js is served compressed and cacheable by the versioned URL the dashboard names: the
partial bundle when it is installed at the plotly package's version, else the full one."""

from __future__ import annotations

import re
from collections.abc import Callable
from pathlib import Path

from starlette.testclient import TestClient

from app.web import COMPILE_HINT, plotly_js_path, plotly_js_version

SRC = re.compile(r'<meta name="plotly-src" content="(/static/vendor/plotly-[\w.-]+\.min\.js)">')


def test_plotly_is_versioned_compressed_and_revalidated(client: TestClient) -> None:
    """The page names /static/vendor/plotly-VERSION.min.js; it comes gzip-compressed, V8's
    compile hint first, with an immutable year-long Cache-Control and an ETag that answers 304;
    the page itself loads no plotly script (charts load it when they need it; preload.js
    only preloads it on their routes)."""
    page = client.get("/").text
    m = SRC.search(page)
    assert m, page[:500]
    scripts = re.findall(r"<script[^>]*>", page.split("</head>")[0])
    assert scripts == [
        '<script src="/static/js/preload.js">',  # preloads plotly.js on chart pages only
        '<script type="module" src="/static/js/app.js">',
    ], scripts
    r = client.get(m.group(1), headers={"Accept-Encoding": "gzip"})
    assert r.status_code == 200
    assert r.headers["content-encoding"] == "gzip"
    # V8 compiles it off the main thread while it streams in (the hint must come first).
    assert r.content.startswith(COMPILE_HINT) and b"plotly.js" in r.content[:400]
    assert int(r.headers["content-length"]) < min(2_000_000, len(r.content) / 2)
    assert (
        "immutable" in r.headers["cache-control"]
        and "max-age=31536000" in r.headers["cache-control"]
    )
    again = client.get(m.group(1), headers={"If-None-Match": r.headers["etag"]})
    assert again.status_code == 304 and again.content == b""


def fake_partial(path: Path, version: str, flavour: str = "cartesian") -> Path:
    """A stand-in bundle with plotly's banner (``plotly.js (cartesian - minified) vX``)."""
    banner = f"/**\n* plotly.js ({flavour} - minified) v{version}\n*/\n"
    path.write_text(banner + "window.Plotly = {};\n" + "//" * 400)
    return path


def test_smaller_bundles_are_served_when_installed_at_the_packages_version(
    tmp_path: Path, start_app: Callable[..., TestClient]
) -> None:
    """With the dashboard's own bundle built (scripts/_plotly.sh) the page names its versioned
    URL and that URL serves it; without it (or of another plotly.js version) plotly's partial
    bundle, and without both the plotly package's full bundle (the dashboard is written
    against that version)."""
    version = plotly_js_version()
    own = fake_partial(tmp_path / "dashboard.js", version, "dashboard: core, scatter, heatmap")
    partial = fake_partial(tmp_path / "partial.js", version)
    old = fake_partial(tmp_path / "old.js", "0.0.1")
    missing = tmp_path / "missing.js"
    for own_js, partial_js, flavour, served_js in (
        (own, partial, "dashboard", own),
        (old, partial, "cartesian", partial),
        (missing, partial, "cartesian", partial),
        (own, missing, "dashboard", own),
    ):
        c = start_app(plotly_dashboard_js=own_js, plotly_partial_js=partial_js)
        url = SRC.search(c.get("/").text).group(1)  # type: ignore[union-attr]
        assert url == f"/static/vendor/plotly-{flavour}-{version}.min.js", (own_js, partial_js)
        r = c.get(url)
        served = COMPILE_HINT + served_js.read_bytes()
        assert r.content == served and "immutable" in r.headers["cache-control"]
        assert c.get("/static/vendor/plotly.min.js").content == served

    full = plotly_js_path().read_bytes()
    for other in (old, missing):
        c = start_app(plotly_dashboard_js=missing, plotly_partial_js=other)
        url = SRC.search(c.get("/").text).group(1)  # type: ignore[union-attr]
        assert url == f"/static/vendor/plotly-{version}.min.js", other
        assert c.get(url).content == COMPILE_HINT + full
