# Sourced by scripts/ctlab.sh and scripts/test.sh: choose the Blender LTS series, make sure its
# virtual environment exists with the pinned requirements, then set $PY to its interpreter.
#
# The series: $CTLAB_BLENDER when set (4.5 or 5.2); otherwise 5.2 LTS (the current release,
# built for CPython 3.13) when a working Python 3.13 is found, else 4.5 LTS (CPython 3.11).
# Each series has its own environment, .venv-bpy<series>, made on first use.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"

# A Python of version $1 (e.g. 3.13) that really runs: on PATH (pyenv's shim for a version it
# does not select refuses to run, so each candidate is tried), then pyenv's versions folder.
ctlab_find_python() {
  local want="$1" candidate
  for candidate in "python$want" $(ls -d "${PYENV_ROOT:-$HOME/.pyenv}"/versions/"$want".*/bin/"python$want" 2>/dev/null | sort -V -r) python3; do
    if command -v "$candidate" >/dev/null 2>&1 &&
       [ "$("$candidate" -c 'import sys; print("%d.%d" % sys.version_info[:2])' 2>/dev/null)" = "$want" ]; then
      command -v "$candidate"; return 0
    fi
  done
  return 1
}

# The CPython each series is built for.
ctlab_python_version() {
  case "$1" in 4.5|5.0) echo 3.11 ;; 5.1|5.2) echo 3.13 ;; *) return 1 ;; esac
}

# scripts/version_matrix.sh borrows the two functions above
if [ "${1:-}" = "--functions-only" ]; then return 0; fi

SERIES="${CTLAB_BLENDER:-}"
if [ -z "$SERIES" ]; then
  if ctlab_find_python 3.13 >/dev/null; then SERIES=5.2; else SERIES=4.5; fi
  CTLAB_CHOSEN="chosen: $( [ "$SERIES" = 5.2 ] && echo "Python 3.13 found" || echo "no Python 3.13 found")"
else
  CTLAB_CHOSEN="set by CTLAB_BLENDER"
fi
case "$SERIES" in
  4.5|5.2) ;;
  *) echo "ctlab: error: CTLAB_BLENDER=$SERIES is not a supported LTS series; use 4.5 or 5.2" >&2; exit 2 ;;
esac
PYVER="$(ctlab_python_version "$SERIES")"
VENV="$ROOT/.venv-bpy$SERIES"
REQ="$ROOT/scripts/requirements-$SERIES.txt"
STAMP="$VENV/.requirements.sha256"
want="$(sha256sum "$REQ" | cut -d' ' -f1)"
if [ ! -x "$VENV/bin/python" ] || [ "$(cat "$STAMP" 2>/dev/null)" != "$want" ]; then
  PYTHON="${CTLAB_PYTHON:-}"
  if [ -z "$PYTHON" ]; then
    PYTHON="$(ctlab_find_python "$PYVER")" || {
      echo "ctlab: error: Python $PYVER is needed for Blender $SERIES (bpy is built for it);" \
           "install it or set CTLAB_PYTHON" >&2
      exit 2
    }
  fi
  echo "ctlab: setting up $VENV (Blender $SERIES LTS, $PYTHON; first run only)" >&2
  rm -rf "$VENV"
  "$PYTHON" -m venv "$VENV"
  # --no-compile: pip byte-compiles one file at a time (10 of 26 s); compileall below does
  # it on every core
  "$VENV/bin/python" -m pip install --quiet --no-compile --disable-pip-version-check -r "$REQ" >&2
  echo "$want" > "$STAMP"
fi
# Packages whose own pins clash with ours: without their dependencies (the file says why)
NODEPS="$ROOT/scripts/requirements-nodeps.txt"
NODEPS_STAMP="$VENV/.requirements-nodeps.sha256"
want="$(sha256sum "$NODEPS" | cut -d' ' -f1)"
if [ "$(cat "$NODEPS_STAMP" 2>/dev/null)" != "$want" ]; then
  "$VENV/bin/python" -m pip install --quiet --no-compile --disable-pip-version-check --no-deps \
    -r "$NODEPS" >&2
  echo "$want" > "$NODEPS_STAMP"
fi
PY="$VENV/bin/python"
# Byte-compile the environment once (about 4 s on 2 cores). Where PYTHONDONTWRITEBYTECODE is
# set (it is on this project's machines), Python never writes what it compiles, so every process compiled
# bpy's start-up scripts, Cycles and numpy again: 1.1 s of a ctlab process's 1.75 s start, paid
# by every task of a job and every process a test starts. Python reads the files whatever that
# variable says. A failure here (a file a package ships that does not compile) costs speed only.
if [ ! -e "$VENV/.compiled" ]; then
  "$PY" -m compileall -qq -j 0 "$VENV/lib" >/dev/null 2>&1 || true
  : > "$VENV/.compiled"
fi
echo "ctlab: Blender $SERIES LTS ($CTLAB_CHOSEN; $PY)" >&2
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
