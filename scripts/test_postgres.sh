#!/usr/bin/env bash
# The API tests again, on PostgreSQL: starts a throwaway server (Debian's postgresql package,
# installed with apt-get when missing; see scripts/pg_server.sh) on a free local port, runs
# tests/services and tests/api against it (each test gets its own database,
# TEST_DATABASE_URL), then stops it.
#   bash scripts/test_postgres.sh [pytest arguments]
#   default: -m "not slow or dialect or postgres" -p no:cacheprovider tests/services tests/api
#   (no pytest cache: scripts/test.sh runs this pass beside the SQLite run's tests/engine)
# The pass is there for the database dialect, so by default it leaves out the tests marked
# slow (their time is numerics: simulating, inverting, fuzzing, real-server body limits, which
# the SQLite run has checked) except those marked dialect (transactions, locking,
# concurrency, column types of the answers) or postgres. Every quick test of tests/services
# and tests/api still runs: each reads and writes the database through the app.
# scripts/test.sh calls it after the main run when it is given no arguments.
set -euo pipefail
cd "$(dirname "$0")/.."
. scripts/_venv.sh '.[test]'

port="$(python - <<'PY'
import socket
for port in range(5433, 5500):
    with socket.socket() as s:
        try:
            s.bind(("127.0.0.1", port))
        except OSError:
            continue
        print(port)
        break
PY
)"
dir="$(mktemp -d "${TMPDIR:-/tmp}/trackprofile-pg.XXXXXX")"
cleanup() {
  bash scripts/pg_server.sh stop "$dir" || true
  rm -rf "$dir"
}
trap cleanup EXIT

echo "== PostgreSQL: starting a throwaway server on 127.0.0.1:${port}"
if ! url="$(bash scripts/pg_server.sh start "$dir" "$port")"; then
  if [ "${CI:-}" = true ]; then
    echo "error: no PostgreSQL server could be started for the tests" >&2
    exit 1
  fi
  echo "warning: no PostgreSQL server could be started (needs Debian's postgresql package," \
    "or root/sudo to install it): the PostgreSQL pass is skipped" >&2
  exit 0
fi
echo "== pytest tests/services tests/api on PostgreSQL (${url})"
if [ "$#" -eq 0 ]; then set -- -m "not slow or dialect or postgres" -p no:cacheprovider tests/services tests/api; fi
TEST_DATABASE_URL="$url" python -m pytest "$@"
