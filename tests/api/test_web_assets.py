"""plotly.js is served compressed and cacheable by the versioned URL the dashboard names."""

from __future__ import annotations

import re

from starlette.testclient import TestClient


def test_plotly_is_versioned_compressed_and_revalidated(client: TestClient) -> None:
    """The page names /static/vendor/plotly-VERSION.min.js; it comes gzip-compressed with an
    immutable year-long Cache-Control and an ETag that answers 304; the page itself loads no
    plotly script (charts load it when they need it)."""
    page = client.get("/").text
    m = re.search(
        r'<meta name="plotly-src" content="(/static/vendor/plotly-[\d.]+\.min\.js)">', page
    )
    assert m, page[:500]
    assert "<script" not in page.split("</head>")[0].replace('<script type="module"', "")
    r = client.get(m.group(1), headers={"Accept-Encoding": "gzip"})
    assert r.status_code == 200
    assert r.headers["content-encoding"] == "gzip"
    assert int(r.headers["content-length"]) < 2_000_000 < len(r.content)
    assert (
        "immutable" in r.headers["cache-control"]
        and "max-age=31536000" in r.headers["cache-control"]
    )
    again = client.get(m.group(1), headers={"If-None-Match": r.headers["etag"]})
    assert again.status_code == 304 and again.content == b""
