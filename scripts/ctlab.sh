#!/usr/bin/env bash
# The main job and the batch tools: ./scripts/ctlab.sh matrix [--out DIR] | render ... | compare ...
source "$(dirname "${BASH_SOURCE[0]}")/bootstrap.sh"
exec "$PY" "$ROOT/scripts/ctlab.py" "$@"
