"""Management commands: ``python -m app <command>``.

    migrate              apply the database migrations
    demo                 store a simulated demo run (track "demo", two soft zones) if absent
    create-key NAME [--scopes read,write,admin]
                         create an API key for a pipeline (printed once, stored hashed)
    list-keys            list API keys (id, name, prefix, scopes, state)
    revoke-key ID        revoke an API key
    realign [TRACK ...]  align every run of the tracks again and rebuild their aggregates
                         (all tracks when none is named; runs stored before alignment existed)
    check-aggregates [--fix] [TRACK ...]
                         check that each track's aggregated profile is what its runs make
                         (exit 1 when one differs; --fix rebuilds those that differ)
    worker               process queued runs and calibrations and sweep expired detail, without
                         serving HTTP (``TRACKPROFILE_WORKERS`` threads; stops on SIGTERM/SIGINT):
                         more of these, on any host sharing the database, process more runs
    sweep                remove the detail the retention policy says has expired, now

The database is the service's: ``DATABASE_URL`` or ``TRACKPROFILE_DATA_DIR``.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from sqlalchemy import select
from sqlalchemy.orm import Session

from app.api.convert import simulation_spec
from app.core.config import get_settings
from app.core.scopes import format_scopes, parse_scopes
from app.core.security import generate_key, hash_key, key_prefix
from app.db.base import utcnow
from app.db.migrate import upgrade
from app.db.models import ALIGNMENT_STATUSES, ApiKey, Track
from app.db.session import Database
from app.schemas.simulate import SimulateRequest
from app.services.context import AppContext
from app.services.errors import DomainError
from app.services.run_lifecycle.simulation import simulate_and_submit
from app.services.track.consistency import check_aggregate, rebuild_aggregate
from app.services.track.integrate import realign_track
from app.services.track.surveys import realign_surveys
from engine.errors import EngineError


def _db() -> Database:
    db = Database(get_settings().sqlalchemy_url)
    upgrade(db)
    return db


def cmd_migrate(_ns: argparse.Namespace) -> int:
    db = _db()
    print(f"database at the latest schema: {db.engine.url.render_as_string(hide_password=True)}")
    return 0


def cmd_demo(ns: argparse.Namespace) -> int:
    ctx = AppContext(settings=get_settings(), db=_db())
    # recorded "now" (to the minute): the run page and the register date it like a real pass
    now = utcnow().replace(second=0, microsecond=0)
    body = SimulateRequest(
        track=ns.track, name="Demo run (simulated, two soft zones)", recorded_at=now
    )
    try:
        run_id, created, truth = simulate_and_submit(ctx, simulation_spec(body))
    except (DomainError, EngineError) as exc:
        print(f"demo run not stored: {exc}", file=sys.stderr)
        return 2
    zones = ", ".join(f"{z.start_m:g}-{z.end_m:g} m ({z.loss:.0%} loss)" for z in truth.zones)
    state = "stored" if created else "already stored"
    print(f"demo run {run_id} {state} on track {ns.track!r}: soft zones at {zones}")
    return 0


def cmd_create_key(ns: argparse.Namespace) -> int:
    db = _db()
    try:
        scopes = format_scopes(parse_scopes(ns.scopes or get_settings().default_key_scopes))
    except ValueError as exc:
        print(f"--scopes: {exc}", file=sys.stderr)
        return 2
    key = generate_key()
    with db.session() as s:
        row = ApiKey(name=ns.name, prefix=key_prefix(key), key_hash=hash_key(key), scopes=scopes)
        s.add(row)
        s.commit()
        print(f"API key {row.id} ({ns.name}, scopes: {scopes}) created. Send it as the "
              "X-API-Key header;")  # fmt: skip
        print("it is shown only now (only its hash is stored):")
        print(key)
    return 0


def cmd_list_keys(_ns: argparse.Namespace) -> int:
    with _db().session() as s:
        for k in s.scalars(select(ApiKey).order_by(ApiKey.id)):
            state = f"revoked {k.revoked_at:%Y-%m-%d %H:%M}" if k.revoked_at else "active"
            print(f"{k.id}\t{k.name}\t{k.prefix}...\t{k.scopes}\t{state}")
    return 0


def cmd_revoke_key(ns: argparse.Namespace) -> int:
    with _db().session() as s:
        row = s.get(ApiKey, ns.id)
        if row is None:
            print(f"no API key with id {ns.id}", file=sys.stderr)
            return 2
        if row.revoked_at is None:
            row.revoked_at = utcnow()
            s.commit()
        print(f"API key {row.id} ({row.name}) revoked")
    return 0


def cmd_realign(ns: argparse.Namespace) -> int:
    with _db().session() as s:
        tracks = list(s.scalars(select(Track).order_by(Track.id)))
        if ns.tracks:
            by_ref = {str(t.id): t for t in tracks} | {t.name: t for t in tracks}
            unknown = [ref for ref in ns.tracks if ref not in by_ref]
            if unknown:
                print(f"no track {unknown[0]!r} (give its name or id)", file=sys.stderr)
                return 2
            tracks = [by_ref[ref] for ref in ns.tracks]
        for track in tracks:
            done = realign_track(s, track.id)
            surveys = realign_surveys(s, track.id)
            s.commit()
            counts = {st: sum(1 for _, a in done if a.status == st) for st in ALIGNMENT_STATUSES}
            print(
                f"track {track.id} ({track.name}): {len(done)} runs: {counts['reference']} "
                f"reference, {counts['aligned']} aligned, {counts['placed']} placed, "
                f"{counts['unaligned']} unaligned"
                + (f"; {len(surveys)} surveys" if surveys else "")
            )
    return 0


def _tracks(s: Session, refs: Sequence[str]) -> list[Track] | None:
    tracks = list(s.scalars(select(Track).order_by(Track.id)))
    if not refs:
        return tracks
    by_ref = {str(t.id): t for t in tracks} | {t.name: t for t in tracks}
    unknown = [ref for ref in refs if ref not in by_ref]
    if unknown:
        print(f"no track {unknown[0]!r} (give its name or id)", file=sys.stderr)
        return None
    return [by_ref[ref] for ref in refs]


def cmd_check_aggregates(ns: argparse.Namespace) -> int:
    bad = 0
    with _db().session() as s:
        tracks = _tracks(s, ns.tracks)
        if tracks is None:
            return 2
        for track in tracks:
            chk = check_aggregate(s, track.id)
            state = "ok" if chk.ok else "DIFFERS"
            print(
                f"track {track.id} ({track.name}): {state}: {chk.stored_points} points stored, "
                f"{chk.expected_points} from its runs, {chk.differing_points} differing"
                + (f", levels of runs not stored: {chk.orphan_runs}" if chk.orphan_runs else "")
            )
            if not chk.ok:
                bad += 1
                if ns.fix:
                    rebuild_aggregate(s, track.id)
                    s.commit()
                    print(f"track {track.id} ({track.name}): aggregate rebuilt")
    return 1 if bad and not ns.fix else 0


def cmd_worker(_ns: argparse.Namespace) -> int:
    import signal
    import threading

    from app.services.run_lifecycle.queue import Worker

    ctx = AppContext(settings=get_settings(), db=_db())
    worker = Worker(ctx)
    stop = threading.Event()
    for sig in (signal.SIGTERM, signal.SIGINT):
        signal.signal(sig, lambda *_: stop.set())
    worker.start()
    print(f"worker {worker.id}: {ctx.settings.workers} thread(s)", flush=True)
    while not stop.wait(1.0):
        if not worker.alive:
            print("a worker thread died", file=sys.stderr)
            return 1
    worker.stop()
    ctx.db.dispose()
    return 0


def cmd_sweep(_ns: argparse.Namespace) -> int:
    from app.services.storage.retention import RetentionPolicy, sweep

    settings = get_settings()
    db = _db()
    policy = RetentionPolicy.from_settings(settings)
    expired = dropped = 0
    while True:
        result = sweep(db, policy)
        expired, dropped = expired + result.expired_runs, dropped + result.dropped_logs
        if not result.removed:
            break
    print(f"detail of {expired} runs expired, {dropped} logs dropped")
    return 0


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m app", description="TrackProfile service admin")
    sub = p.add_subparsers(dest="command", required=True)
    sub.add_parser("migrate", help="apply the database migrations").set_defaults(fn=cmd_migrate)
    d = sub.add_parser("demo", help="store a simulated demo run")
    d.add_argument("--track", default="demo", help="track name (default: demo)")
    d.set_defaults(fn=cmd_demo)
    c = sub.add_parser("create-key", help="create an API key")
    c.add_argument("name", help="who or what uses the key, e.g. 'fleet-pipeline'")
    c.add_argument(
        "--scopes",
        help="what the key may do, comma-separated: read, write (uploads, changes), admin "
        "(deletes, vehicle edits, calibration); default TRACKPROFILE_DEFAULT_KEY_SCOPES "
        "(all three)",
    )
    c.set_defaults(fn=cmd_create_key)
    sub.add_parser("list-keys", help="list API keys").set_defaults(fn=cmd_list_keys)
    r = sub.add_parser("revoke-key", help="revoke an API key")
    r.add_argument("id", type=int, help="key id (see list-keys)")
    r.set_defaults(fn=cmd_revoke_key)
    a = sub.add_parser("realign", help="align the runs of tracks again, rebuild aggregates")
    a.add_argument("tracks", nargs="*", metavar="TRACK", help="track names or ids (default all)")
    a.set_defaults(fn=cmd_realign)
    k = sub.add_parser("check-aggregates", help="check each track's aggregate against its runs")
    k.add_argument("--fix", action="store_true", help="rebuild the aggregates that differ")
    k.add_argument("tracks", nargs="*", metavar="TRACK", help="track names or ids (default all)")
    k.set_defaults(fn=cmd_check_aggregates)
    sub.add_parser("worker", help="process queued runs (no HTTP)").set_defaults(fn=cmd_worker)
    sub.add_parser("sweep", help="remove expired run detail now").set_defaults(fn=cmd_sweep)
    return p


def main(argv: Sequence[str] | None = None) -> int:
    """Run a management command; returns the exit code."""
    ns = build_parser().parse_args(argv)
    return int(ns.fn(ns))


if __name__ == "__main__":
    raise SystemExit(main())
