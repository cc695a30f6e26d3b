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
    the page itself loads no plotly script (charts load it when they need it)."""
    page = client.get("/").text
    m = SRC.search(page)
    assert m, page[:500]
    assert "<script" not in page.split("</head>")[0].replace('<script type="module"', "")
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


def fake_partial(path: Path, version: str) -> Path:
    """A stand-in partial bundle with plotly's banner (``plotly.js (cartesian - minified) vX``)."""
    banner = f"/**\n* plotly.js (cartesian - minified) v{version}\n*/\n"
    path.write_text(banner + "window.Plotly = {};\n" + "//" * 400)
    return path


def test_partial_bundle_is_served_when_installed_at_the_packages_version(
    tmp_path: Path, start_app: Callable[..., TestClient]
) -> None:
    """With the partial bundle installed (scripts/_plotly.sh) the page names its own versioned
    URL and that URL serves it; a partial bundle of another plotly.js version, or none, gives the
    plotly package's full bundle (the dashboard is written against that version)."""
    version = plotly_js_version()
    partial = fake_partial(tmp_path / "partial.js", version)
    c = start_app(plotly_partial_js=partial)
    url = SRC.search(c.get("/").text).group(1)  # type: ignore[union-attr]
    assert url == f"/static/vendor/plotly-cartesian-{version}.min.js"
    r = c.get(url)
    served = COMPILE_HINT + partial.read_bytes()
    assert r.content == served and "immutable" in r.headers["cache-control"]
    assert c.get("/static/vendor/plotly.min.js").content == served

    full = plotly_js_path().read_bytes()
    for other in (fake_partial(tmp_path / "old.js", "0.0.1"), tmp_path / "missing.js"):
        c = start_app(plotly_partial_js=other)
        url = SRC.search(c.get("/").text).group(1)  # type: ignore[union-attr]
        assert url == f"/static/vendor/plotly-{version}.min.js", other
        assert c.get(url).content == COMPILE_HINT + full
