#!/usr/bin/env bash
# One command that installs the test dependencies and runs the checks and the test suite:
#   bash scripts/test.sh [pytest arguments]
# Lint (ruff), type check (mypy: engine and app), then pytest. Installs Debian's chromium and npm
# for the browser tests when missing (needs root or sudo; without it those tests are skipped).
# Without arguments it then runs the API tests again on PostgreSQL (scripts/test_postgres.sh:
# installs Debian's postgresql when missing and starts a throwaway server);
# TRACKPROFILE_TEST_POSTGRES=0 skips that pass.
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
echo "== pytest"
python -m pytest "$@"

if [ "$#" -eq 0 ] && [ "${TRACKPROFILE_TEST_POSTGRES:-1}" != 0 ]; then
  bash scripts/test_postgres.sh
fi
