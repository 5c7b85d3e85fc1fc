"""Write the node group the extension ships (addon/data/node_group.blend, with node_group.json:
the source digest it was built from and the Blender that built it), so that no first use
builds its 1,271 nodes (blender/node_group.py ``ensure_group``). Built with the oldest Blender
series the extension supports (4.5), whose file every newer series opens. Run it after
changing the group's sources (node_groups/cook_torrance.toml, the model's interface,
blender/node_group.py, blender/node_compiler.py); tests/render/test_build_once.py fails until
it is run.

    CTLAB_BLENDER=4.5 ./scripts/ctlab.sh --version >/dev/null   # sets up .venv-bpy4.5
    .venv-bpy4.5/bin/python scripts/build_node_group.py
"""

import json
import os
import sys
import tempfile
from pathlib import Path

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

OLDEST = (4, 5)  # blender_manifest.toml's blender_version_min


def main() -> None:
    import bpy

    from addon.blender import node_group
    from addon.core.files import atomic_path, write_text

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
    with tempfile.TemporaryDirectory() as tmp:
        staged = Path(tmp) / node_group.GROUP_FILE
        bpy.data.libraries.write(str(staged), {group}, compress=True)
        with atomic_path(node_group.SHIPPED) as out:
            out.write_bytes(staged.read_bytes())
    write_text(
        node_group.SHIPPED_SOURCES,
        json.dumps({"digest": digest, "blender": bpy.app.version_string}, indent=2) + "\n",
    )
    print(f"wrote {node_group.SHIPPED} ({node_group.SHIPPED.stat().st_size} bytes), {digest}")


if __name__ == "__main__":
    main()
    sys.stdout.flush()
    os._exit(0)  # bpy as a module can hang at exit (tests/conftest.py)
