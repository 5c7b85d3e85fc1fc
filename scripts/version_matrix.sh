#!/usr/bin/env bash
# Run the test suite against several Blender-as-a-module releases, each in its own virtual
# environment (.venv-bpy<series>, made on first use with the CPython the series is built for:
# 3.11 for 4.5 and 5.0, 3.13 for 5.1 and 5.2), and write the result table to docs/versions.md:
# one row per series, the rows of series not run this time kept from out/versions/<series>.row.
# Usage: ./scripts/version_matrix.sh [4.5 5.0 5.1 5.2] [-- pytest arguments]
# The LTS series (4.5, 5.2) use the pinned scripts/requirements-<series>.txt (the README's
# test command's own environments); the others the series' newest release from PyPI.
set -uo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
series=(); extra=()
while [ $# -gt 0 ]; do
  if [ "$1" = "--" ]; then shift; extra=("$@"); break; fi
  series+=("$1"); shift
done
[ ${#series[@]} -eq 0 ] && series=(4.5 5.0 5.1 5.2)
LOG="$ROOT/out/versions"; mkdir -p "$LOG"
BASE_LD_LIBRARY_PATH="${LD_LIBRARY_PATH:-}"
for s in "${series[@]}"; do
  LD_LIBRARY_PATH="$BASE_LD_LIBRARY_PATH"
  venv="$ROOT/.venv-bpy$s"
  case "$s" in
    4.5|5.2)
      (CTLAB_BLENDER=$s source "$ROOT/scripts/bootstrap.sh") >&2 ||
        { echo "| $s | — | install failed |" > "$LOG/$s.row"; continue; } ;;
    5.0|5.1)
      if [ ! -x "$venv/bin/python" ] || ! "$venv/bin/python" -c "import bpy, hypothesis" 2>/dev/null; then
        pyver="$(source "$ROOT/scripts/bootstrap.sh" --functions-only; ctlab_python_version "$s")"
        python="$(source "$ROOT/scripts/bootstrap.sh" --functions-only; ctlab_find_python "$pyver")" ||
          { echo "| $s | — | Python $pyver not found |" > "$LOG/$s.row"; continue; }
        numpy=$([ "$pyver" = 3.11 ] && echo "numpy<2" || echo "numpy")
        echo "version_matrix: installing bpy $s.* into $venv ($python)" >&2
        rm -rf "$venv"
        "$python" -m venv "$venv" && "$venv/bin/python" -m pip install --quiet \
          --disable-pip-version-check "bpy==$s.*" "$numpy" \
          $(grep -E '^(pytest|hypothesis)==' "$ROOT/scripts/requirements-5.2.txt") >&2 ||
          { echo "| $s | — | install failed |" > "$LOG/$s.row"; continue; }
      fi ;;
    *) echo "version_matrix: error: unknown series $s; use 4.5 5.0 5.1 5.2" >&2; exit 2 ;;
  esac
  # some wheels (5.0) carry libraries such as libtbb.so.12 in bpy/lib without finding them
  site="$("$venv/bin/python" -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')"
  export LD_LIBRARY_PATH="$site/bpy/lib${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
  version="$("$venv/bin/python" -c 'import bpy; print(bpy.app.version_string)' 2>/dev/null | tail -1)"
  pyv="$("$venv/bin/python" -c 'import platform, numpy; print(platform.python_version(), "/ numpy", numpy.__version__)')"
  echo "version_matrix: bpy $version: running the suite (log: $LOG/$s.log)" >&2
  start=$(date +%s)
  "$venv/bin/python" -m pytest tests -q -ra -p no:cacheprovider "${extra[@]}" > "$LOG/$s.log" 2>&1
  rc=$?
  secs=$(( $(date +%s) - start ))
  summary="$(grep -E '^(=+ )?[0-9]+ (passed|failed)|(passed|failed|error).* in [0-9.]+s' "$LOG/$s.log" | tail -1 | sed 's/=//g; s/^ *//; s/ *$//')"
  verdict=$([ $rc -eq 0 ] && echo pass || echo FAIL)
  echo "| $version | Python $pyv | $verdict | ${summary:-exit $rc} (${secs} s) |" > "$LOG/$s.row"
done
rows=()
for s in 4.5 5.0 5.1 5.2; do [ -f "$LOG/$s.row" ] && rows+=("$(cat "$LOG/$s.row")"); done
{
  echo "# Blender versions"
  echo
  echo "Made by \`./scripts/version_matrix.sh\` on $(date -u +%Y-%m-%d) (bpy from PyPI, $(nproc) cores,"
  echo "CPU only). Each row is the whole suite in that version's own environment."
  echo
  echo "| bpy | Python | suite | pytest summary |"
  echo "|---|---|---|---|"
  printf '%s\n' "${rows[@]}"
  echo
  echo "Logs: out/versions/<series>.log. What differs between the versions, and how the add-on"
  echo "handles it: addon/blender/compat.py and docs/testing.md, *Blender versions*."
} > "$ROOT/docs/versions.md.tmp" && mv "$ROOT/docs/versions.md.tmp" "$ROOT/docs/versions.md"
cat "$ROOT/docs/versions.md"
grep -q FAIL "$ROOT/docs/versions.md" && exit 1 || exit 0
