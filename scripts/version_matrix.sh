#!/usr/bin/env bash
# Run the test suite against several Blender-as-a-module releases, each in its own virtual
# environment (.venv-bpy<series>, created on first use; the pinned 4.5 uses the project's own
# .venv), and write the result table to docs/versions.md: one row per series, the rows of
# series not run this time kept from out/versions/<series>.row.
# Usage: ./scripts/version_matrix.sh [4.2 4.5 5.0] [-- pytest arguments]
# The series' newest patch release is used, with numpy < 2 (bpy 4.x cannot import numpy 2).
set -uo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
series=(); extra=()
while [ $# -gt 0 ]; do
  if [ "$1" = "--" ]; then shift; extra=("$@"); break; fi
  series+=("$1"); shift
done
[ ${#series[@]} -eq 0 ] && series=(4.2 4.5 5.0)
PYTHON="${CTLAB_PYTHON:-python3.11}"
command -v "$PYTHON" >/dev/null || { echo "version_matrix: error: $PYTHON not found; set CTLAB_PYTHON" >&2; exit 2; }
LOG="$ROOT/out/versions"; mkdir -p "$LOG"
rows=()
for s in "${series[@]}"; do
  venv="$ROOT/.venv-bpy$s"
  if [ "$s" = "4.5" ]; then
    (source "$ROOT/scripts/bootstrap.sh") >&2 || { echo "| 4.5 | — | install failed |" > "$LOG/4.5.row"; continue; }
    venv="$ROOT/.venv"
  fi
  if [ ! -x "$venv/bin/python" ] || ! "$venv/bin/python" -c "import bpy" 2>/dev/null; then
    echo "version_matrix: installing bpy $s.* into $venv" >&2
    rm -rf "$venv"
    "$PYTHON" -m venv "$venv" && "$venv/bin/python" -m pip install --quiet \
      --disable-pip-version-check "bpy==$s.*" "numpy<2" pytest >&2 || { echo "| $s | — | install failed |" > "$LOG/$s.row"; continue; }
  fi
  # bpy 5.0's wheel carries libtbb.so.12 in bpy/lib but does not find it on every system
  export LD_LIBRARY_PATH="$venv/lib/python3.11/site-packages/bpy/lib${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
  version="$("$venv/bin/python" -c 'import bpy; print(bpy.app.version_string)' 2>/dev/null | tail -1)"
  echo "version_matrix: bpy $version: running the suite (log: $LOG/$s.log)" >&2
  start=$(date +%s)
  "$venv/bin/python" -m pytest tests -q -ra -p no:cacheprovider "${extra[@]}" > "$LOG/$s.log" 2>&1
  rc=$?
  secs=$(( $(date +%s) - start ))
  summary="$(grep -E '^(=+ )?[0-9]+ (passed|failed)|(passed|failed|error).* in [0-9.]+s' "$LOG/$s.log" | tail -1 | sed 's/=//g; s/^ *//; s/ *$//')"
  verdict=$([ $rc -eq 0 ] && echo pass || echo FAIL)
  echo "| $version | $verdict | ${summary:-exit $rc} (${secs} s) |" > "$LOG/$s.row"
done
rows=()
for row in "$LOG"/*.row; do [ -f "$row" ] && rows+=("$(cat "$row")"); done
{
  echo "# Blender versions"
  echo
  echo "Made by \`./scripts/version_matrix.sh\` on $(date -u +%Y-%m-%d) (bpy from PyPI,"
  echo "Python $("$PYTHON" -c 'import platform; print(platform.python_version())'), $(nproc) cores, CPU only)."
  echo
  echo "| bpy | suite | pytest summary |"
  echo "|---|---|---|"
  printf '%s\n' "${rows[@]}"
  echo
  echo "Logs: out/versions/<series>.log."
} > "$ROOT/docs/versions.md.tmp" && mv "$ROOT/docs/versions.md.tmp" "$ROOT/docs/versions.md"
cat "$ROOT/docs/versions.md"
grep -q FAIL "$ROOT/docs/versions.md" && exit 1 || exit 0
