#!/usr/bin/env bash
# The test suite (real Blender: real Cycles, real OSL, real renders). Extra arguments go to pytest.
source "$(dirname "${BASH_SOURCE[0]}")/bootstrap.sh"
cd "$ROOT"
exec "$PY" -m pytest tests -ra "$@"
