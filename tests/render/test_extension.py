"""The repository root is the extension: Blender's own tool builds and validates the zip; it
installs and enables headless into a temporary user folder, and its operators build the matrix
and bake the world there. Rebuilding never deletes a user's objects."""

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import bpy

from helpers import ROOT
from unity_fixtures import snapshot, write_project
from addon.core import osl_source

BLENDER_EXT = (
    Path(bpy.utils.resource_path('LOCAL'))
    / "scripts"
    / "addons_core"
    / "bl_pkg"
    / "cli"
    / "blender_ext.py"
)


def _ext(*args):
    return subprocess.run(
        [sys.executable, str(BLENDER_EXT), *map(str, args)],
        capture_output=True,
        text=True,
        timeout=120,
    )


def test_zip_builds_validates_installs_and_builds_the_matrix(tmp_path):
    dist = tmp_path / "dist"
    dist.mkdir()
    p = _ext("build", "--source-dir", ROOT, "--output-dir", dist)
    assert p.returncode == 0, p.stdout + p.stderr
    zips = list(dist.glob("cook_torrance_lab-*.zip"))
    assert len(zips) == 1
    p = _ext("validate", zips[0])
    assert p.returncode == 0 and "Success" in p.stdout, p.stdout + p.stderr
    import zipfile

    names = zipfile.ZipFile(zips[0]).namelist()
    assert "osl/cook_torrance.osl" in names and "__init__.py" in names
    # the shader's parts travel with it (the add-on inlines them when it loads the source)
    assert {f"osl/{p.name}" for p in osl_source.parts()} <= set(names)
    # the manifest's licences travel with the code: the GPL's text and the font's OFL
    assert "LICENSE" in names and "addon/data/font_atlas.LICENSE.txt" in names
    assert "GNU GENERAL PUBLIC LICENSE" in (ROOT / "LICENSE").read_text()[:200]
    assert "addon/data/dominant_cook_torrance.npy" in names
    assert "addon/data/correction_tables.npz" in names and "addon/data/node_group.blend" in names
    assert not any(n.startswith(("tests/", "scripts/", ".venv", ".ci")) for n in names)

    assert "wheels/pyyaml-6.0.4-py3-none-any.whl" in names  # Unity's .mat files need it
    project = write_project(tmp_path / "unity")
    before = snapshot(project)
    script = textwrap.dedent(f"""
        import importlib.machinery, sys
        class OnlyTheExtensionsYaml:  # this venv has PyYAML; an installed Blender has none
            def find_spec(self, name, path=None, target=None):
                if name.split(".")[0] != "yaml":
                    return None
                where = [p for p in sys.path if p.startswith({str(tmp_path / "user")!r})]
                spec = importlib.machinery.PathFinder.find_spec(name, path or where)
                if spec is None:
                    raise ImportError("no PyYAML among the extension's wheels")
                return spec
        sys.meta_path.insert(0, OnlyTheExtensionsYaml())
        import bpy
        bpy.utils.expose_bundled_modules()
        bpy.ops.extensions.package_install_files(filepath={str(zips[0])!r}, repo="user_default",
                                                 enable_on_install=True)
        addon = bpy.context.preferences.addons["bl_ext.user_default.cook_torrance_lab"]
        assert addon.preferences.implementation == "nodes" and addon.preferences.samples == 64
        print("CLASSES=" + ",".join(sorted(n for n in dir(bpy.types) if n.startswith("CTLAB_"))))
        props = sorted(n for n in dir(bpy.types.Material) if n.startswith("ctlab_"))
        print("PROPS=" + ",".join(props))
        print("MENU=" + ",".join(f.__name__ for f in bpy.types.NODE_MT_add._dyn_ui_initialize()))
        user = bpy.data.objects.new("User Empty", None)
        bpy.context.scene.collection.objects.link(user)
        for _ in range(2):
            done = bpy.ops.ctlab.build_sphere_matrix(rows=2, cols=3, resolution=64)
            assert done == {{'FINISHED'}}
        tagged = [o for o in bpy.data.objects if o.get("ctlab_matrix")]
        assert len([o for o in tagged if o.type == 'MESH']) == 6, len(tagged)
        assert "User Empty" in bpy.data.objects
        mat = bpy.data.materials["Cook-Torrance Matrix"]
        node = next(n for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeGroup")
        script = node.node_tree.nodes["Cook-Torrance Lab shader"]  # its shared compiled shader
        assert any(s.identifier == "albedo" for s in script.inputs), "the OSL shader has no sockets"
        assert len(node.inputs) > 50, "the shared shader's group has no inputs"
        try:                       # headless, an operator's ERROR report raises RuntimeError
            bpy.ops.ctlab.build_sphere_matrix(hdri="/nonexistent.exr")
            raise AssertionError("a missing HDRI was accepted")
        except RuntimeError as exc:
            assert "HDRI not found: /nonexistent.exr" in str(exc), exc
        assert len([o for o in bpy.data.objects if o.get("ctlab_matrix")]) == 8
        # the bake operator bakes the world's Environment Texture (forest.exr) into the cache
        assert bpy.ops.ctlab.bake_environment() == {{'FINISHED'}}
        import json, pathlib
        bake = pathlib.Path(bpy.context.scene["ctlab_ibl_bake"])
        info = json.loads((bake / "bake.json").read_text())
        assert info["source"].endswith("forest.exr") and len(info["levels"]) == 7, info
        try:
            bpy.ops.ctlab.bake_environment(filepath="/nonexistent.exr")
            raise AssertionError("a missing HDRI was baked")
        except RuntimeError as exc:
            assert "HDRI not found: /nonexistent.exr" in str(exc), exc
        # Unity's files through the wheel the extension ships
        assert bpy.ops.ctlab.import_unity(directory={str(project)!r}) == {{'FINISHED'}}
        import yaml
        assert yaml.__file__.startswith({str(tmp_path / "user")!r}), yaml.__file__
        assert {{"Brick", "Old", "AlbedoAlpha", "Missing"}} <= set(bpy.data.materials.keys())
        print("EXTENSION-OK")
    """)
    env = dict(os.environ, BLENDER_USER_RESOURCES=str(tmp_path / "user"))
    p = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, env=env, timeout=300
    )
    assert "EXTENSION-OK" in p.stdout, p.stdout[-2000:] + p.stderr[-2000:]
    assert snapshot(project) == before  # the Unity folder is only read
    # the same panels, operators, preferences, properties and menu entry as the source tree
    from addon.ui import properties, register, panels as ui

    lines = dict(
        line.split("=", 1)
        for line in p.stdout.splitlines()
        if line.startswith(("CLASSES=", "PROPS=", "MENU="))
    )
    assert lines["CLASSES"].split(",") == sorted(
        c.__name__ for c in register.CLASSES if "_OT_" in c.__name__ or "_PT_" in c.__name__
    )
    assert lines["PROPS"].split(",") == sorted(properties.NAMES[0][1])
    assert ui.draw_add_menu.__name__ in lines["MENU"].split(",")
