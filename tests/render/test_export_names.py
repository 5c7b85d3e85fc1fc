"""``ctlab export``'s names and identities against hostile files (addon/core/export/network.py
``export_names``, addon/blender/material_export.py, addon/blender/user_blend.py): materials
whose names sanitise alike or differ by case get distinct files, packed images and prims; a
local material and one linked from a library under the same name keep their own textures and
bindings; a missing library, a texture file name of undecodable bytes and a header-only .blend
are refused in one line (exit 2, nothing written); a 240-character extension is made a valid
name. The .usda is read back with USD's own reader (Blender's bundled pxr)."""

import json
import os
import shutil
import subprocess
import sys
import textwrap

import pytest

from helpers import ROOT

CTLAB = [sys.executable, str(ROOT / "scripts" / "ctlab.py")]

# The bad-input table's rows (docs/bad-input.md): ID -> the test of this file
CASES = {
    "export-names-collide": "test_names_that_sanitise_alike_get_their_own_files",
    "export-linked-same-name": "test_local_and_linked_material_of_one_name",
    "export-library-missing": "test_missing_library_is_refused",
    "export-texture-long-extension": "test_texture_with_a_long_extension",
    "export-texture-non-utf8": "test_texture_file_name_not_utf8_is_refused",
    "blend-header-only": "test_header_only_blend_is_refused",
}

BUILD = textwrap.dedent(r'''
    import os, sys
    sys.path.insert(0, sys.argv[1])
    import bpy
    from addon import blender  # noqa: F401
    from addon.blender import materials, model_node
    from addon.core.model import ModelOptions

    out = sys.argv[2]
    opts = ModelOptions(light_transport="scene", g_model="smith_ggx_correlated",
                        diffuse_model="lambert", ibl="split_sum")

    def png(path, value):
        img = bpy.data.images.new("tmp", 4, 4)
        img.pixels = [value, value, value, 1.0] * 16
        img.filepath_raw = os.path.join(out, "tmp.png")
        img.file_format = 'PNG'
        img.save()
        bpy.data.images.remove(img)
        os.rename(os.path.join(out, "tmp.png"), path)
        return path

    def obj(name, mat):
        bpy.ops.mesh.primitive_cube_add()
        o = bpy.context.object
        o.name = name
        o.data.materials.append(mat)

    def material(name, albedo=None, metallic=None):
        m = materials.model_material(name, impl="nodes", options=opts, albedo_image=(
            bpy.data.images.load(albedo) if albedo else None))
        if metallic:
            t = m.node_tree.nodes.new("ShaderNodeTexImage")
            t.image = bpy.data.images.load(metallic)
            t.image.colorspace_settings.name = "Non-Color"
            m.node_tree.links.new(
                t.outputs["Color"], model_node.surface_input(model_node.find(m), "metallic"))
        return m

    def save(name):
        bpy.ops.wm.save_as_mainfile(filepath=os.path.join(out, name), compress=False)
        bpy.ops.wm.read_factory_settings(use_empty=True)

    bpy.ops.wm.read_factory_settings(use_empty=True)
    # a library with a material "Gold" and its own albedo texture (the same image name,
    # "paint.png", as the local one's, in another folder)
    os.makedirs(os.path.join(out, "lib"))
    m = material("Gold", albedo=png(os.path.join(out, "lib", "paint.png"), 0.2))
    m.use_fake_user = True
    save("lib/lib.blend")
    # names that sanitise alike (and differ by case), each with a metallic map
    for i, name in enumerate(("Gold/1", "Gold?1", "gold_1")):
        obj(f"Obj{i}", material(name, metallic=png(os.path.join(out, f"met{i}.png"), 0.25 * i)))
    save("collide.blend")
    # a local "Gold" and the library's "Gold"
    obj("Local", material("Gold", albedo=png(os.path.join(out, "paint.png"), 0.8)))
    with bpy.data.libraries.load(os.path.join(out, "lib", "lib.blend"), link=True) as (s, d):
        d.materials = ["Gold"]
    obj("Linked", d.materials[0])
    save("linked.blend")
    # textures of a 240-character extension and of a non-UTF-8 file name
    obj("A", material("M", albedo=png(os.path.join(out, "t." + "x" * 240), 0.5)))
    save("long.blend")
    bad = os.fsdecode(os.path.join(os.fsencode(out), b"caf\xe9.png"))
    obj("A", material("M", albedo=png(bad, 0.5)))
    save("nonutf8.blend")
''')


@pytest.fixture(scope="module")
def blends(tmp_path_factory):
    folder = tmp_path_factory.mktemp("names")
    run = subprocess.run(
        [sys.executable, "-c", BUILD, str(ROOT), str(folder)],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert run.returncode == 0, run.stderr[-3000:]
    return folder


def ctlab(*args):
    return subprocess.run([*CTLAB, *map(str, args)], capture_output=True, text=True, timeout=300)


def _refused(run, out, *words):
    """Exit 2, one line on stderr holding ``words``, no traceback, nothing written."""
    assert run.returncode == 2, (run.returncode, run.stderr[-2000:])
    lines = run.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("ctlab: error: "), run.stderr[-2000:]
    for w in words:
        assert w in lines[0], lines[0]
    assert "Traceback" not in run.stdout + run.stderr
    assert not out.exists()


def _stage(path):
    from addon.blender.compat import bundled_module

    bundled_module("pxr")
    from pxr import Usd

    stage = Usd.Stage.Open(str(path))
    assert stage is not None
    return stage


def _bound_albedo(stage, obj):
    """The material bound to /Objects/OBJ and its albedo image's file."""
    from pxr import UsdShade

    material = UsdShade.MaterialBindingAPI(stage.GetPrimAtPath(f"/Objects/{obj}"))
    material = material.ComputeBoundMaterial()[0]
    path = material.GetPath().pathString
    tex = UsdShade.Shader(stage.GetPrimAtPath(f"{path}/albedo_image"))
    return path, tex.GetInput("file").Get().path


def test_names_that_sanitise_alike_get_their_own_files(blends, tmp_path):
    """Materials "Gold/1", "Gold?1" and "gold_1" (alike once sanitised, or but for case): three
    .mtlx files, three glTF packed images each from its own map, three USD prims each bound to its
    own object; the command line says "exact in Cycles/OSL closures" for MaterialX and lists
    the 0.96 diffuse scale for glTF."""
    out = tmp_path / "mtlx"
    run = ctlab("export", blends / "collide.blend", "--format", "materialx", "--out", out)
    assert run.returncode == 0, run.stderr
    mtlx = sorted(p.name for p in out.glob("*.mtlx"))
    assert len({n.casefold() for n in mtlx}) == 3, mtlx
    assert "Gold/1: exact in Cycles/OSL closures" in run.stdout, run.stdout
    assert run.stdout.count("exact in Cycles/OSL closures") == 3
    # each .mtlx names its own material (the doc of its surfacematerial) and metallic map
    docs = {}
    for p in out.glob("*.mtlx"):
        text = p.read_text()
        docs[text.split('type="material" doc="')[1].split('"')[0]] = text
    assert sorted(docs) == ["Gold/1", "Gold?1", "gold_1"]
    for i, name in enumerate(("Gold/1", "Gold?1", "gold_1")):
        assert f"textures/met{i}.png" in docs[name]

    out = tmp_path / "gltf"
    run = ctlab("export", blends / "collide.blend", "--format", "gltf", "--out", out)
    assert run.returncode == 0, run.stderr
    doc = json.loads((out / "collide.gltf").read_text())
    uris = {}
    for m in doc["materials"]:
        tex = m["pbrMetallicRoughness"]["metallicRoughnessTexture"]["index"]
        uris[m["name"]] = doc["images"][doc["textures"][tex]["source"]]["uri"]
        assert any("0.96" in n for n in m["extras"]["cook_torrance_lab"]["not_carried"])
    assert len({u.casefold() for u in uris.values()}) == 3, uris
    from addon.core import compare

    for i, name in enumerate(("Gold/1", "Gold?1", "gold_1")):
        pixels = compare.read_image(out / uris[name])
        assert pixels[..., 2].mean() == pytest.approx(round(0.25 * i * 255) / 255, abs=1e-6)
    assert "exact" not in run.stdout.replace("export ", "")
    assert run.stdout.count("the diffuse scale 0.96") == 3
    assert f"done: 4 files in {out}" in run.stdout  # the .gltf and three packed images

    out = tmp_path / "usd"
    run = ctlab("export", blends / "collide.blend", "--format", "usd", "--out", out)
    assert run.returncode == 0, run.stderr
    stage = _stage(out / "collide.usda")
    from pxr import UsdShade

    paths = set()
    for i in range(3):
        bound = UsdShade.MaterialBindingAPI(stage.GetPrimAtPath(f"/Objects/Obj{i}"))
        prim = bound.ComputeBoundMaterial()[0].GetPrim()
        paths.add(prim.GetPath().pathString)
        assert prim.GetCustomDataByKey("blender_name") == ("Gold/1", "Gold?1", "gold_1")[i]
    assert len(paths) == 3, paths


def test_local_and_linked_material_of_one_name(blends, tmp_path):
    """A local "Gold" and "Gold" linked from lib/lib.blend, each with an image named
    paint.png: each object is bound to its own material, which reads its own texture (both
    copied, under distinct names); the glTF file holds both, the linked one's library in
    extras."""
    out = tmp_path / "usd"
    run = ctlab("export", blends / "linked.blend", "--format", "usd", "--out", out)
    assert run.returncode == 0, run.stderr
    stage = _stage(out / "linked.usda")
    local, local_file = _bound_albedo(stage, "Local")
    linked, linked_file = _bound_albedo(stage, "Linked")
    assert local != linked
    assert local_file != linked_file
    from addon.core import compare

    assert compare.read_image(out / local_file)[..., 0].mean() == pytest.approx(204 / 255)
    assert compare.read_image(out / linked_file)[..., 0].mean() == pytest.approx(51 / 255)
    assert stage.GetPrimAtPath(linked).GetCustomDataByKey("blender_library").endswith("lib.blend")

    out = tmp_path / "gltf"
    run = ctlab("export", blends / "linked.blend", "--format", "gltf", "--out", out)
    assert run.returncode == 0, run.stderr
    doc = json.loads((out / "linked.gltf").read_text())
    assert [m["name"] for m in doc["materials"]] == ["Gold", "Gold"]
    files = [
        doc["images"][
            doc["textures"][m["pbrMetallicRoughness"]["baseColorTexture"]["index"]]["source"]
        ]["uri"]
        for m in doc["materials"]
    ]
    assert len(set(files)) == 2, files
    libs = [m["extras"]["cook_torrance_lab"].get("library", "") for m in doc["materials"]]
    assert libs[0] == "" and libs[1].endswith("lib.blend"), libs


def test_missing_library_is_refused(blends, tmp_path):
    """The .blend links "Gold" from a library that is not there: one line naming the library
    and its path, exit 2, nothing written (before: exit 0, the material left out)."""
    folder = tmp_path / "moved"
    folder.mkdir()
    shutil.copy(blends / "linked.blend", folder / "linked.blend")
    shutil.copy(blends / "paint.png", folder / "paint.png")  # the local material's: found
    out = tmp_path / "out"
    run = ctlab("export", folder / "linked.blend", "--format", "usd", "--out", out)
    _refused(run, out, "lib.blend", "whose file is missing", str(folder / "lib" / "lib.blend"))


def test_texture_with_a_long_extension(blends, tmp_path):
    """An image whose file has a 240-character extension is copied under a valid, bounded
    name (its format's extension) and referenced by it."""
    out = tmp_path / "out"
    run = ctlab("export", blends / "long.blend", "--format", "materialx", "--out", out)
    assert run.returncode == 0, run.stderr
    names = [p.name for p in (out / "textures").iterdir()]
    assert names == ["t.png"], names
    assert "textures/t.png" in (out / "M.mtlx").read_text()


def test_texture_file_name_not_utf8_is_refused(blends, tmp_path):
    """An image whose file name is not UTF-8 (b"caf\\xe9.png"): one line naming the image
    and its file (the undecodable byte shown as U+FFFD), exit 2, nothing written."""
    for fmt in ("materialx", "gltf"):
        out = tmp_path / fmt
        run = ctlab("export", blends / "nonutf8.blend", "--format", fmt, "--out", out)
        _refused(run, out, "image 'caf", "not valid UTF-8", "caf\ufffd.png")


@pytest.mark.parametrize("head", [b"BLENDER-v502", b"BLENDER17-01v0502", b"BLENDER-v502REND"])
def test_header_only_blend_is_refused(tmp_path, head):
    """A file of a .blend's header alone (or cut short after it): ctlab's one line before
    Blender reads it (Blender's own "Malloc returns null" never printed), for export and
    scene."""
    blend = tmp_path / "cut.blend"
    blend.write_bytes(head)
    for args in (("export", blend, "--format", "usd"), ("scene", blend)):
        out = tmp_path / "out"
        run = ctlab(*args, "--out", out)
        _refused(run, out, "is not a whole Blender file", str(blend))
        assert "Malloc" not in run.stdout + run.stderr


def test_header_check_keeps_whole_files(blends):
    """Files Blender wrote (plain, compressed) pass the header check (addon/blender/
    user_blend.py ``check_blend_file``); one cut before its end block does not."""
    from addon.blender.user_blend import check_blend_file
    from addon.core.errors import UserError

    for path in (blends / "collide.blend", ROOT / "addon" / "data" / "node_group.blend"):
        assert check_blend_file(path) == path.resolve()  # plain; zstd
    cut = blends / "cut-short.blend"
    cut.write_bytes((blends / "collide.blend").read_bytes()[:-40])
    try:
        with pytest.raises(UserError, match="cut short"):
            check_blend_file(cut)
    finally:
        os.remove(cut)
