"""Storage without HTTP: migrations up and down, processes migrating together, where the
database lives, the per-chainage block codec."""

from __future__ import annotations

import time

import numpy as np
import pytest

from app.core.config import Settings
from app.db.migrate import alembic_config, current_revision, upgrade
from app.db.session import Database


def test_migrations_downgrade_and_upgrade(tmp_path) -> None:
    """The migrations can be undone and redone (a broken downgrade would block rollbacks)."""
    from alembic import command

    db = Database(f"sqlite:///{tmp_path / 'm.db'}")
    upgrade(db)
    cfg = alembic_config()
    with db.engine.begin() as conn:
        cfg.attributes["connection"] = conn
        command.downgrade(cfg, "base")
    assert current_revision(db) is None
    upgrade(db)
    assert current_revision(db) is not None
    db.dispose()


@pytest.mark.sqlite_only
def test_processes_starting_together_take_turns_to_migrate(tmp_path, monkeypatch) -> None:
    """Two upgrades of one new SQLite file at once (two app processes starting together):
    the second looks at the schema only after the first has committed, so both succeed. The
    lock's release is slowed down here: were it released before the commit, the second would
    find no tables yet and fail on creating them ('table tracks already exists')."""
    import fcntl
    import threading
    import types

    import app.db.migrate as migrate

    def slow_unlock(fh, op):  # noqa: ANN001, ANN202
        fcntl.flock(fh, op)
        if op == fcntl.LOCK_UN:
            time.sleep(0.5)

    monkeypatch.setattr(migrate, "fcntl", types.SimpleNamespace(
        flock=slow_unlock, LOCK_EX=fcntl.LOCK_EX, LOCK_UN=fcntl.LOCK_UN))  # fmt: skip
    url = f"sqlite:///{tmp_path / 'together.db'}"
    errors: list[BaseException] = []

    def start() -> None:
        db = Database(url)
        try:
            upgrade(db)
        except BaseException as exc:  # noqa: BLE001 - reported below
            errors.append(exc)
        finally:
            db.dispose()

    threads = [threading.Thread(target=start) for _ in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(60)
    assert not errors, errors
    db = Database(url)
    assert current_revision(db) is not None
    db.dispose()


def test_database_location_from_environment(monkeypatch, tmp_path) -> None:
    """DATABASE_URL selects the database; otherwise it is trackprofile.db under
    TRACKPROFILE_DATA_DIR (default ./data)."""
    monkeypatch.delenv("DATABASE_URL", raising=False)
    monkeypatch.setenv("TRACKPROFILE_DATA_DIR", str(tmp_path / "d"))
    assert Settings().sqlalchemy_url == f"sqlite:///{tmp_path / 'd' / 'trackprofile.db'}"
    monkeypatch.setenv("DATABASE_URL", "sqlite:////srv/x.db")
    assert Settings().sqlalchemy_url == "sqlite:////srv/x.db"
    monkeypatch.delenv("TRACKPROFILE_DATA_DIR")
    monkeypatch.delenv("DATABASE_URL")
    assert Settings().sqlalchemy_url.endswith("/data/trackprofile.db")


def test_new_database_directory_is_created(tmp_path) -> None:
    """A data directory that does not exist yet is created with the database."""
    db = Database(f"sqlite:///{tmp_path / 'new' / 'deeper' / 't.db'}")
    upgrade(db)
    assert (tmp_path / "new" / "deeper" / "t.db").is_file()
    db.dispose()


def test_a_block_decodes_any_subset_of_its_columns_exactly() -> None:
    """Decoding only some columns (a window read of the level needs two of seven) gives those
    columns exactly as the full decode does, gaps (NaN) included, in the order asked."""
    from app.services.storage.packing import decode_block, encode_block

    rng = np.random.default_rng(3)
    scales = (1e-4, 1e-4, 1.0)
    cols = [rng.normal(0, 2, 4001), rng.normal(0, 2, 4001), rng.normal(9e4, 3e3, 4001)]
    cols[1][100:140] = np.nan
    cols[2][-5:] = np.nan
    blob = encode_block(cols, scales)
    full = decode_block(blob, scales)
    assert [np.isnan(c).sum() for c in full] == [0, 40, 5]
    for which in ([0], [1], [2], [2, 0], [1, 2]):
        part = decode_block(blob, scales, which)
        assert len(part) == len(which)
        for got, j in zip(part, which, strict=True):
            np.testing.assert_array_equal(got, full[j])


def test_kept_unpacks_answer_as_unpacking_and_stay_within_their_memory() -> None:
    """A blob met again gives the array unpacked the first time (the same numbers as
    unpacking it, NaN kept; read-only, as it is shared); a blob of other content is unpacked
    anew; the oldest go once the kept bytes exceed the bound."""
    from app.services.storage.packing import KeptUnpacks, pack_f4, unpack_f4

    rng = np.random.default_rng(4)
    rows = [rng.normal(0, 1, 1000).astype(np.float32) for _ in range(6)]
    rows[0][10:20] = np.nan
    blobs = [pack_f4(r) for r in rows]
    one = len(blobs[0]) + 8 * 1000
    kept = KeptUnpacks(max_bytes=3 * one + 100)
    first = kept(blobs[0])
    np.testing.assert_array_equal(first, unpack_f4(blobs[0]))
    assert not first.flags.writeable
    with pytest.raises(ValueError):
        first[0] = 1.0
    assert kept(bytes(bytearray(blobs[0]))) is first  # the same content, another object
    other = kept(blobs[1])
    np.testing.assert_array_equal(other, unpack_f4(blobs[1]))
    for b in blobs[2:]:
        kept(b)
    assert kept.nbytes <= kept.max_bytes
    assert kept(blobs[0]) is not first  # dropped as the oldest, unpacked again
    np.testing.assert_array_equal(kept(blobs[0]), first)
