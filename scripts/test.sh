#!/usr/bin/env bash
# One command that installs the test dependencies and runs the checks and the test suite:
#   bash scripts/test.sh [pytest arguments]
# Lint (ruff), type check (mypy: engine and app), then pytest. Installs Debian's chromium and npm
# for the browser tests when missing (needs root or sudo; without it those tests are skipped).
# Without arguments it also runs the API tests again on PostgreSQL (scripts/test_postgres.sh:
# installs Debian's postgresql when missing and starts a throwaway server);
# TRACKPROFILE_TEST_POSTGRES=0 skips that pass. That pass runs beside tests/engine: the
# engine's tests are pure numerics in one process (no database, server, port or shared file),
# so they and the PostgreSQL pass each keep one core of a 2-core machine busy where one
# pytest alone leaves the second mostly idle; tests/services, tests/api and tests/browser
# (live servers, timing ceilings, the browser) run afterwards with the machine to themselves.
# TRACKPROFILE_TEST_OVERLAP=0 runs everything one after the other.
set -euo pipefail
cd "$(dirname "$0")/.."
. scripts/_venv.sh '.[test]'

# Debian packages the tests need when missing: chromium (browser tests), npm (axe-core and
# the dashboard's plotly.js: _plotly.sh). Needs root or sudo; without it the browser tests are
# skipped.
missing=""
[ -x /usr/bin/chromium ] || missing="$missing chromium"
command -v npm >/dev/null 2>&1 || missing="$missing npm"
if [ -n "$missing" ]; then
  sudo=""
  if [ "$(id -u)" != 0 ] && command -v sudo >/dev/null 2>&1; then sudo="sudo -n"; fi
  if [ "$(id -u)" = 0 ] || [ -n "$sudo" ]; then
    echo "installing${missing} (Debian packages) for the browser tests"
    # shellcheck disable=SC2086
    $sudo apt-get update -qq && DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq $missing \
      || echo "warning:${missing} could not be installed; browser tests may be skipped or fail" >&2
  else
    echo "warning: no root or sudo to install${missing}; browser tests will be skipped" >&2
  fi
fi
. scripts/_plotly.sh

# axe-core (npm) for the accessibility checks of the browser tests (tests/browser/harness.py).
if command -v npm >/dev/null 2>&1; then
  echo "== axe-core (npm) for the browser tests' accessibility checks"
  npm install --no-save --no-audit --no-fund --no-package-lock --prefix .cache/npm axe-core@4.14.1 >/dev/null
else
  echo "warning: npm is missing: the browser tests install axe-core themselves or fail" >&2
fi

echo "== ruff check"
python -m ruff check .
echo "== mypy (engine, app)"
python -m mypy
python -m mypy app
if [ "$#" -gt 0 ]; then
  echo "== pytest"
  exec python -m pytest "$@"
fi

postgres="${TRACKPROFILE_TEST_POSTGRES:-1}"
if [ "$postgres" = 0 ] || [ "${TRACKPROFILE_TEST_OVERLAP:-1}" = 0 ]; then
  echo "== pytest"
  python -m pytest
  if [ "$postgres" != 0 ]; then bash scripts/test_postgres.sh; fi
  exit 0
fi

pg_log="$(mktemp "${TMPDIR:-/tmp}/trackprofile-pg-pass.XXXXXX")"
echo "== PostgreSQL pass (scripts/test_postgres.sh) beside tests/engine; its output follows them"
bash scripts/test_postgres.sh >"$pg_log" 2>&1 &
pg_pid=$!
trap 'kill "$pg_pid" 2>/dev/null || true' EXIT
echo "== pytest tests/engine (SQLite run, part 1 of 2)"
engine_rc=0
python -m pytest tests/engine || engine_rc=$?
pg_rc=0
wait "$pg_pid" || pg_rc=$?
trap - EXIT
cat "$pg_log"
rm -f "$pg_log"
echo "== pytest tests/services tests/api tests/browser (SQLite run, part 2 of 2)"
rest_rc=0
python -m pytest --ignore=tests/engine || rest_rc=$?
echo "== exit codes: tests/engine ${engine_rc}, PostgreSQL pass ${pg_rc}, the rest ${rest_rc}"
[ "$engine_rc" = 0 ] && [ "$pg_rc" = 0 ] && [ "$rest_rc" = 0 ]
