#!/usr/bin/env bash
# Build the extension zip with the chosen Blender's own tool (blender_ext.py build), then
# validate it: ./scripts/build_extension.sh [OUTPUT_DIR]   (default dist/)
source "$(dirname "${BASH_SOURCE[0]}")/bootstrap.sh"
cd "$ROOT"
out="${1:-dist}"
mkdir -p "$out"
tool="$("$PY" -c 'import bpy, pathlib; print(pathlib.Path(bpy.utils.resource_path("LOCAL")) / "scripts" / "addons_core" / "bl_pkg" / "cli" / "blender_ext.py")' | tail -1)"
"$PY" "$tool" build --source-dir . --output-dir "$out"
zip="$(ls -t "$out"/cook_torrance_lab-*.zip | head -1)"
"$PY" "$tool" validate "$zip"
