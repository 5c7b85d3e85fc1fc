# Sourced by scripts/ctlab.sh and scripts/test.sh: make sure .venv exists with the pinned
# requirements (bpy 4.5 needs CPython 3.11), then set $PY to its interpreter.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
VENV="$ROOT/.venv"
REQ="$ROOT/scripts/requirements.txt"
STAMP="$VENV/.requirements.sha256"
want="$(sha256sum "$REQ" | cut -d' ' -f1)"
if [ ! -x "$VENV/bin/python" ] || [ "$(cat "$STAMP" 2>/dev/null)" != "$want" ]; then
  PYTHON="${CTLAB_PYTHON:-}"
  if [ -z "$PYTHON" ]; then
    for candidate in python3.11 python3; do
      if command -v "$candidate" >/dev/null 2>&1 &&
         [ "$("$candidate" -c 'import sys; print(sys.version_info[:2] == (3, 11))')" = True ]; then
        PYTHON="$candidate"; break
      fi
    done
  fi
  if [ -z "$PYTHON" ]; then
    echo "ctlab: error: Python 3.11 is needed (bpy 4.5 is built for it); set CTLAB_PYTHON" >&2
    exit 2
  fi
  echo "ctlab: setting up $VENV (bpy 4.5, numpy<2, pytest; first run only)" >&2
  "$PYTHON" -m venv "$VENV"
  "$VENV/bin/python" -m pip install --quiet --disable-pip-version-check -r "$REQ" >&2
  echo "$want" > "$STAMP"
fi
PY="$VENV/bin/python"
# EEVEE renders headless through Mesa's EGL: install its libraries when they are missing and
# the system's package manager can be used (otherwise the EEVEE test and --engine eevee fail).
# (ldconfig's list is read whole first: with pipefail, grep -q closing the pipe early would
# make the pipeline fail by SIGPIPE.)
libs="$(ldconfig -p 2>/dev/null || true)"
if ! grep -q "libEGL.so.1" <<< "$libs" || ! grep -q "libgbm.so.1" <<< "$libs"; then
  if command -v apt-get >/dev/null 2>&1 && [ "$(id -u)" = 0 ]; then
    echo "ctlab: installing Mesa's EGL for EEVEE (libegl1 libegl-mesa0 libgl1-mesa-dri libgbm1)" >&2
    apt-get install -y -qq libegl1 libegl-mesa0 libgl1-mesa-dri libgbm1 >&2 || \
      echo "ctlab: warning: could not install Mesa's EGL; EEVEE renders will fail" >&2
  else
    echo "ctlab: warning: Mesa's EGL (libEGL.so.1, libgbm.so.1) is missing; install libegl1" \
         "libegl-mesa0 libgl1-mesa-dri libgbm1 for EEVEE" >&2
  fi
fi
