#!/usr/bin/env bash
# The test suite (real Blender: real Cycles, real OSL, real renders), in three tiers that are
# folders: tests/unit (no Blender), tests/render, tests/slow. Extra arguments go to pytest;
# --quick runs tests/unit alone (seconds), for the edit-test loop; naming test files or
# folders (tests/render/FILE.py, tests/slow) runs those alone; --lint-only runs ruff alone.
source "$(dirname "${BASH_SOURCE[0]}")/bootstrap.sh"
cd "$ROOT"
if [ "${1:-}" = "--lint-only" ]; then         # ruff (ruff.toml): lint and format, no tests
  "$PY" -m ruff check . && exec "$PY" -m ruff format --check .
fi
args=()
where=(tests)                   # the whole suite, unless test files or folders are named
for a in "$@"; do
  if [ "$a" = "--quick" ]; then where=(tests/unit)
  else
    args+=("$a")
    case "$a" in tests/*|./tests/*) where=() ;; esac
  fi
done
exec "$PY" -m pytest "${where[@]}" -ra "${args[@]}"
