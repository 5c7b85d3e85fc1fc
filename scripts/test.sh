#!/usr/bin/env bash
# The test suite (real Blender: real Cycles, real OSL, real renders). Extra arguments go to
# pytest; --quick runs the fast tier alone (no renders: the pure core, the builders, the
# interface and the architecture checks), for the edit-test loop. Naming test files
# (tests/FILE.py) runs those alone.
source "$(dirname "${BASH_SOURCE[0]}")/bootstrap.sh"
cd "$ROOT"
args=()
where=(tests)                   # the whole suite, unless test files or folders are named
for a in "$@"; do
  if [ "$a" = "--quick" ]; then args+=(-m quick)
  else
    args+=("$a")
    case "$a" in tests/*|./tests/*) where=() ;; esac
  fi
done
exec "$PY" -m pytest "${where[@]}" -ra "${args[@]}"
