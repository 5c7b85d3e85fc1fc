#!/usr/bin/env bash
# The developers' entry: ./scripts/dev.sh TARGET [ARGS...]   (CTLAB_BLENDER=4.5|5.2 picks the series)
# Sets up the series' environment as the README's commands do (scripts/bootstrap.sh), then runs
# the target with it. The product's own entries stay ./scripts/ctlab.sh and ./scripts/test.sh.
#
#   bench               scripts/bench.py: the benchmark (bench/, docs/testing.md "Benchmark")
#   build_node_group    the shipped node group (run with CTLAB_BLENDER=4.5, the oldest series)
#   build_tables        the shipped correction and environment tables (addon/data/)
#   build_font          the report's font atlas (addon/data/font_atlas.*)
#   build_seed_textures the matrix's bundled texture pair (addon/data/seed_*.png)
#   build_yaml_wheel    wheels/pyyaml-*.whl, the PyYAML the extension ships
#   scene_images        the README's scene images
#   albedo_study        scripts/albedo_scaling_study.py (a numpy study, docs/testing.md)
#   extension           scripts/build_extension.sh: the extension's zip, built and validated
set -euo pipefail
target="${1:-}"
case "$target" in
  bench|build_node_group|build_tables|build_font|build_seed_textures|build_yaml_wheel|scene_images)
    script="$target.py" ;;
  albedo_study) script="albedo_scaling_study.py" ;;
  extension) shift; exec "$(dirname "${BASH_SOURCE[0]}")/build_extension.sh" "$@" ;;
  *)
    sed -n '2,/^set -euo/p' "${BASH_SOURCE[0]}" | sed '$d; s/^# \{0,1\}//' >&2
    [ -z "$target" ] || [ "$target" = "-h" ] || [ "$target" = "--help" ] || {
      echo "dev.sh: error: no target $target" >&2; exit 2; }
    exit 0 ;;
esac
shift
source "$(dirname "${BASH_SOURCE[0]}")/bootstrap.sh"
exec "$PY" "$ROOT/scripts/$script" "$@"
