# Sourced by serve.sh and test.sh: create .venv (Python 3.11) and install the project into it.
#   usage: . scripts/_venv.sh '.'        (the service)
#          . scripts/_venv.sh '.[test]'  (the service and the test tools)
# The venv sees the system's site-packages, so packages already installed on the machine are
# reused and nothing is downloaded that is already there; pip fetches only what is missing.
# The install is redone only when pyproject.toml (or the requested extras) change.

spec="${1:-.}"
py="${PYTHON:-}"
if [ -z "$py" ]; then
  if command -v python3.11 >/dev/null 2>&1; then py=python3.11; else py=python3; fi
fi
if ! "$py" -c 'import sys; sys.exit(0 if sys.version_info[:2] >= (3, 11) else 1)'; then
  echo "error: Python 3.11 or newer is needed (found $("$py" --version 2>&1))" >&2
  return 1 2>/dev/null || exit 1
fi
if [ ! -x .venv/bin/python ]; then
  echo "creating .venv with $("$py" --version)"
  "$py" -m venv --system-site-packages .venv
fi
# shellcheck disable=SC1091
. .venv/bin/activate
stamp=".venv/.installed-$(printf '%s' "$spec" | tr -c 'A-Za-z0-9' '_')"
want="$(sha256sum pyproject.toml | cut -d' ' -f1)"
if [ ! -f "$stamp" ] || [ "$(cat "$stamp")" != "$want" ]; then
  echo "installing the project ($spec) into .venv"
  python -m pip install --quiet --disable-pip-version-check -e "$spec"
  printf '%s' "$want" > "$stamp"
fi
