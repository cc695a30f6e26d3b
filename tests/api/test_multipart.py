"""The multipart upload's file part is read into memory (no temporary file, no copy back),
with Starlette's limits and messages on everything else."""

from __future__ import annotations

import starlette.formparsers as formparsers

from api.api_support import row_counts, upload


def _upload_spooled_bytes(client, synthetic_run, monkeypatch) -> int:
    """Upload the synthetic run (stored: 201); the bytes written to Starlette's spooled
    temporary files meanwhile."""
    written: list[int] = []

    class Spy(formparsers.SpooledTemporaryFile):  # type: ignore[misc]
        def write(self, data):  # noqa: ANN001, ANN202
            written.append(len(data))
            return super().write(data)

    monkeypatch.setattr(formparsers, "SpooledTemporaryFile", Spy)
    data = synthetic_run["csv"]
    r = upload(
        client, data, "run.csv", track="T", start_chainage_m=synthetic_run["start_chainage_m"]
    )
    assert r.status_code == 201, r.text
    assert r.json()["n_samples"] > 0 and r.json()["original_filename"] == "run.csv"
    return sum(written)


def test_file_part_is_read_into_memory_not_spooled(client, settings, synthetic_run, monkeypatch):
    assert _upload_spooled_bytes(client, synthetic_run, monkeypatch) == 0


def test_form_limits_keep_their_messages(client, settings) -> None:
    before = row_counts(settings)
    cases = {
        "Too many fields. Maximum number of fields is 64.": client.post(
            "/api/v1/runs", files={"file": ("a.csv", b"x")}, data={f"f{i}": "x" for i in range(65)}
        ),
        "Too many files. Maximum number of files is 1.": client.post(
            "/api/v1/runs", files=[("file", ("a.csv", b"x")), ("other", ("b.csv", b"y"))]
        ),
        "Part exceeded maximum size of 1024KB.": client.post(
            "/api/v1/runs", files={"file": ("a.csv", b"x")}, data={"track": "t" * (1 << 21)}
        ),
        "Missing boundary in multipart.": client.post(
            "/api/v1/runs", content=b"abc", headers={"content-type": "multipart/form-data"}
        ),
    }  # fmt: skip
    for message, r in cases.items():
        assert r.status_code == 400, (message, r.text)
        assert r.json()["detail"]["message"] == message
    assert row_counts(settings) == before


def test_this_starlette_has_the_buffering_hooks() -> None:
    """If this fails, a Starlette upgrade changed the parser's internals: uploads still work
    (spooled by request.form(), the next test), but a large log is read ~1 s slower; adapt
    app/api/multipart.py's hooks to the new parser."""
    import app.api.multipart as multipart

    assert multipart.BUFFERING


def test_without_the_hooks_uploads_and_limits_still_work(
    client, settings, synthetic_run, monkeypatch
) -> None:
    """The fallback for a Starlette without the hooks: the same run stored, the same limit
    messages (request.form()'s), nothing stored for a refused form."""
    import app.api.multipart as multipart

    monkeypatch.setattr(multipart, "BUFFERING", False)
    spooled = _upload_spooled_bytes(client, synthetic_run, monkeypatch)
    assert spooled == len(synthetic_run["csv"])  # request.form()'s spooled file: the fallback
    before = row_counts(settings)
    r = client.post("/api/v1/runs", files=[("file", ("a.csv", b"x")), ("other", ("b.csv", b"y"))])
    assert r.status_code == 400
    assert r.json()["detail"]["message"] == "Too many files. Maximum number of files is 1."
    r = client.post(
        "/api/v1/runs", files={"log": ("a.csv", b"x")}, data={"file": "not a file", "track": "T"}
    )
    assert r.status_code == 422 and r.json()["detail"]["field"] == "file", r.text
    assert row_counts(settings) == before
