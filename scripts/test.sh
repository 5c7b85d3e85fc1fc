#!/usr/bin/env bash
# The test suite (real Blender: real Cycles, real OSL, real renders), in three tiers that are
# folders: tests/unit (no Blender), tests/render, tests/slow. Extra arguments go to pytest;
# --quick runs tests/unit alone (seconds), for the edit-test loop; naming test files or
# folders (tests/render/FILE.py, tests/slow) runs those alone; --lint-only runs ruff alone;
# --series-subset runs only the tests whose subject depends on Blender's version (CI's second
# series: see docs/testing.md "Which tests run on both series").
#
# A run of more than the unit tier spreads the test files over worker processes
# (pytest-xdist, a file's tests kept together so its shared renders are made once), the
# longest files first (tests/conftest.py LONGEST_FILES): one per core, at most 4;
# CTLAB_TEST_WORKERS sets the number (0: one process, no workers).
source "$(dirname "${BASH_SOURCE[0]}")/bootstrap.sh"
cd "$ROOT"
if [ "${1:-}" = "--lint-only" ]; then         # ruff (ruff.toml): lint and format, no tests
  "$PY" -m ruff check . && exec "$PY" -m ruff format --check .
fi
args=()
where=(tests)                   # the whole suite, unless test files or folders are named
quick=0
for a in "$@"; do
  if [ "$a" = "--quick" ]; then where=(tests/unit); quick=1
  elif [ "$a" = "--series-subset" ]; then args+=(-m "not one_series")
  else
    args+=("$a")
    case "$a" in tests/*|./tests/*) where=() ;; esac
  fi
done
workers="${CTLAB_TEST_WORKERS:-}"
if [ -n "$workers" ] && ! [[ "$workers" =~ ^[0-9]+$ ]]; then
  echo "ctlab: error: CTLAB_TEST_WORKERS=$workers is not a number of workers (0 or more)" >&2
  exit 2
fi
if [ -z "$workers" ]; then
  workers="$(nproc 2>/dev/null || echo 1)"
  [ "$workers" -gt 4 ] && workers=4
fi
if [ "$quick" = 0 ] && [ "$workers" -gt 1 ]; then
  args=(-n "$workers" --dist loadfile --no-loadscope-reorder "${args[@]}")
fi
exec "$PY" -m pytest "${where[@]}" -ra "${args[@]}"
