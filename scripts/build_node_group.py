"""Write the node group the extension ships (addon/data/node_group.blend, with node_group.json:
the source digest it was built from and the Blender that built it), so that no first use
builds its 1,271 nodes (blender/node_group.py ``ensure_group``). Built with the oldest Blender
series the extension supports (4.5), whose file every newer series opens. Run it after
changing the group's sources (node_groups/cook_torrance.toml's data, the model's interface,
the code of core/node_description.py, blender/node_group.py, blender/node_compiler.py and
blender/node_closures.py: ``source_digest``; comments and docstrings do not count,
core/source_code.py); tests/render/test_build_once.py fails until it is run.

    CTLAB_BLENDER=4.5 ./scripts/ctlab.sh --version >/dev/null   # sets up .venv-bpy4.5
    CTLAB_BLENDER=4.5 ./scripts/dev.sh build_node_group
"""

import json
import os
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

OLDEST = (4, 5)  # blender_manifest.toml's blender_version_min


def main() -> None:
    import bpy

    from addon.blender import node_group
    from addon.core.files import atomic_paths

    if tuple(bpy.app.version[:2]) != OLDEST:
        raise SystemExit(
            f"build_node_group: run it with Blender {OLDEST[0]}.{OLDEST[1]} "
            f"(.venv-bpy4.5), not {bpy.app.version_string}: newer files are not read the same "
            "by older Blenders"
        )
    bpy.ops.wm.read_factory_settings(use_empty=True)
    digest = node_group.source_digest()
    name = node_group.load_description()["group"]["name"]
    group = node_group.build_group(name)
    group[node_group.SOURCE_HASH] = digest
    # both files or neither: a group beside another digest's record is never shipped
    with atomic_paths(node_group.SHIPPED, node_group.SHIPPED_SOURCES) as (blend, record):
        bpy.data.libraries.write(str(blend), {group}, compress=True)
        record.write_text(
            json.dumps({"digest": digest, "blender": bpy.app.version_string}, indent=2) + "\n"
        )
    print(f"wrote {node_group.SHIPPED} ({node_group.SHIPPED.stat().st_size} bytes), {digest}")


if __name__ == "__main__":
    main()
    sys.stdout.flush()
    os._exit(0)  # bpy as a module can hang at exit (tests/conftest.py)
