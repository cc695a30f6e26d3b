#!/usr/bin/env bash
# One command from a fresh clone to a running service with a demo run:
#   bash scripts/serve.sh        ->  http://127.0.0.1:8000
# Installs into .venv (and plotly's partial bundle from npm when npm is there: _plotly.sh),
# applies the migrations, stores a simulated demo run (track "demo", two soft zones) and starts
# uvicorn. HOST and PORT override the address; the database is
# ./data/trackprofile.db unless DATABASE_URL or TRACKPROFILE_DATA_DIR say otherwise.
set -euo pipefail
cd "$(dirname "$0")/.."
. scripts/_venv.sh '.'
. scripts/_plotly.sh
python -m app migrate
python -m app demo
host="${HOST:-127.0.0.1}"
port="${PORT:-8000}"
echo "serving on http://${host}:${port}  (dashboard at /, API docs at /docs; Ctrl-C stops)"
# uvicorn's own limits (a proxy in front adds header/body timeouts and TLS: see README);
# h11 named: its header-size limit holds even where httptools (no such limit) is installed;
# no "server: uvicorn" header (it tells a prober which server and so which flaws to try)
exec python -m uvicorn app.main:app --host "$host" --port "$port" --http h11 --no-server-header \
  --timeout-keep-alive 5 --limit-concurrency "${LIMIT_CONCURRENCY:-256}"
