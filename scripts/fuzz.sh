#!/usr/bin/env bash
# The schema fuzz test, longer and in all six configurations (open, read-only, keys required
# without a key, read scope, write scope, every scope), on a seeded database; the allow-list
# is tests/api/schemathesis.toml. docs/fuzzing.md says what it found.
#   bash scripts/fuzz.sh                 (FUZZ_MAX_EXAMPLES, FUZZ_STATEFUL_STEPS, FUZZ_SEED)
set -euo pipefail
cd "$(dirname "$0")/.."
. scripts/_venv.sh '.[test]'
export FUZZ_CONFIGURATIONS=all
export FUZZ_MAX_EXAMPLES="${FUZZ_MAX_EXAMPLES:-25}"
export FUZZ_STATEFUL_STEPS="${FUZZ_STATEFUL_STEPS:-10}"
exec python -m pytest tests/api/test_schema_fuzz.py -p no:cacheprovider -q --durations=10 "$@"
