"""``ctlab import-unity`` (addon/jobs/unity_import_job.py, addon/blender/unity_import.py) on a
Unity project of the tests' own making (tests/unity_fixtures.py: both .mat layouts, old and
new .meta files, tiny PNGs): each Standard material's values (colours decoded), its textures
wired with their colour spaces and alpha mode, tiling and offset, the other shaders listed
and absent, a texture guid that resolves nowhere warned about, the folder byte-identical
afterwards; bad input refused in one line; and the trip Blender -> Unity files
(core/unity/mat.py ``unity_outputs``) -> Blender: the values within 1/255 and a small Cycles
render of the re-imported material equal to the original's."""

import subprocess
import sys

import bpy
import numpy as np
import pytest

import unity_fixtures as fx
from helpers import ROOT

from addon.blender import light_sync, material_export, materials, model_node, renderer
from addon.core import compare
from addon.core.model import ARTIST, ModelOptions
from addon.jobs import cli
from addon.jobs import unity_import_job

CTLAB = [sys.executable, str(ROOT / "scripts" / "ctlab.py")]

# ID of docs/bad-input.md -> the test here that checks it
CASES = {
    "unity-not-yaml": "test_bad_input_is_refused",
    "unity-old-layout": "test_bad_input_is_refused",
    "unity-out-not-blend": "test_bad_input_is_refused",
    "unity-out-exists": "test_bad_input_is_refused",
    "unity-no-standard": "test_bad_input_is_refused",
    "unity-guid-missing": "test_import_unity_project",
}


def _srgb(c):
    return c / 12.92 if c <= 0.04045 else ((c + 0.055) / 1.055) ** 2.4


def _png(path):
    """An 8-bit PNG's values, alpha unassociated, rows top first (as the fixtures write
    them)."""
    from addon.core.hdri import read_pixels

    return read_pixels(path, keep=4)


def _linked(sock):
    assert sock.is_linked, sock.name
    return sock.links[0].from_node, sock.links[0].from_socket


@pytest.fixture(scope="module")
def imported(tmp_path_factory):
    """The fixture project imported by the command line, in a child process."""
    root = fx.write_project(tmp_path_factory.mktemp("unity") / "Project")
    before = fx.snapshot(root)
    out = tmp_path_factory.mktemp("blend") / "unity.blend"
    run = subprocess.run(
        [*CTLAB, "import-unity", str(root), "--out", str(out)],
        capture_output=True,
        text=True,
        timeout=300,
    )
    return root, before, out, run


def test_import_unity_project(imported):
    root, before, out, run = imported
    assert run.returncode == 0, run.stderr
    assert fx.snapshot(root) == before  # nothing of the Unity folder written
    skipped = [line for line in run.stdout.splitlines() if "skipped" in line]
    assert len(skipped) == 3, run.stdout
    assert any("Spec.mat" in s and "Specular setup" in s for s in skipped)
    assert any("Autodesk.mat" in s and "Autodesk Interactive" in s for s in skipped)
    assert any("Toon.mat" in s and "Toon.shader" in s for s in skipped)
    assert "occlusion map (_OcclusionMap) not carried" in run.stdout
    assert f"guid {fx.G_GONE}" in run.stderr and "kept without it" in run.stderr

    bpy.ops.wm.open_mainfile(filepath=str(out), load_ui=False)
    mats = {m.name: m for m in bpy.data.materials}
    assert set(mats) == {"Brick", "Old", "AlbedoAlpha", "Missing"}
    for m in mats.values():
        assert m.use_fake_user and model_node.find(m) is not None

    # Brick: _Color (decoded) x _MainTex, metallic = R, smoothness = A x 0.8 of an sRGB
    # metallic map, a normal map of strength 0.5, _MainTex's tiling and offset on every map
    node = model_node.find(mats["Brick"])
    mix, _ = _linked(model_node.surface_input(node, "albedo"))
    assert mix.bl_idname == "ShaderNodeMix" and mix.blend_type == 'MULTIPLY'
    color_b = next(s for s in mix.inputs if s.identifier == "B_Color").default_value
    assert tuple(color_b)[:3] == pytest.approx([_srgb(c) for c in fx.BRICK_COLOR[:3]], abs=1e-3)
    albedo_tex, _ = _linked(next(s for s in mix.inputs if s.identifier == "A_Color"))
    assert albedo_tex.image.filepath.endswith("albedo.png")
    assert albedo_tex.image.colorspace_settings.name == "sRGB"
    assert albedo_tex.image.alpha_mode == 'CHANNEL_PACKED'
    split, sock = _linked(model_node.surface_input(node, "metallic"))
    assert split.bl_idname == "ShaderNodeSeparateColor" and sock.name == "Red"
    metal_tex, _ = _linked(split.inputs["Color"])
    assert metal_tex.image.filepath.endswith("metal.png")
    assert metal_tex.image.colorspace_settings.name == "sRGB"  # as its .meta says
    assert metal_tex.image.alpha_mode == 'CHANNEL_PACKED'
    scale, _ = _linked(model_node.surface_input(node, "smoothness"))
    assert scale.operation == 'MULTIPLY' and scale.inputs[1].default_value == pytest.approx(0.8)
    src, sock = _linked(scale.inputs[0])
    assert src == metal_tex and sock.name == "Alpha"
    nmap, _ = _linked(model_node.surface_input(node, "normal"))
    assert nmap.bl_idname == "ShaderNodeNormalMap" and nmap.space == 'TANGENT'
    assert nmap.inputs["Strength"].default_value == pytest.approx(0.5)
    normal_tex, _ = _linked(nmap.inputs["Color"])
    assert normal_tex.image.colorspace_settings.name == "Non-Color"
    for tex in (albedo_tex, metal_tex, normal_tex):
        mapping, _ = _linked(tex.inputs["Vector"])
        assert tuple(mapping.inputs["Scale"].default_value) == pytest.approx((2, 3, 1))
        assert tuple(mapping.inputs["Location"].default_value) == pytest.approx((0.25, 0.5, 0))

    # Old (Unity 5's pairs): constants
    node = model_node.find(mats["Old"])
    albedo = model_node.surface_input(node, "albedo")
    assert not albedo.is_linked
    assert tuple(albedo.default_value)[:3] == pytest.approx(
        [_srgb(c) for c in fx.OLD_COLOR[:3]], abs=1e-3
    )
    assert model_node.surface_input(node, "metallic").default_value == pytest.approx(0.3, abs=1e-3)
    smooth = model_node.surface_input(node, "smoothness").default_value
    assert smooth == pytest.approx(0.65, abs=1e-3)

    # AlbedoAlpha: white _Color, the albedo straight in; smoothness = its alpha x 0.5
    node = model_node.find(mats["AlbedoAlpha"])
    tex, _ = _linked(model_node.surface_input(node, "albedo"))
    assert tex.bl_idname == "ShaderNodeTexImage" and tex.image.filepath.endswith("albedo_a.png")
    scale, _ = _linked(model_node.surface_input(node, "smoothness"))
    assert scale.inputs[1].default_value == pytest.approx(0.5)
    assert _linked(scale.inputs[0]) == (tex, tex.outputs["Alpha"])

    # Missing: kept with its values, no texture
    node = model_node.find(mats["Missing"])
    assert not model_node.surface_input(node, "albedo").is_linked
    assert model_node.surface_input(node, "smoothness").default_value == pytest.approx(0.75)


def _run(argv, capsys):
    code = cli.main([str(a) for a in argv])
    return code, capsys.readouterr().err


def test_bad_input_is_refused(tmp_path, capsys):
    project = fx.write_project(tmp_path / "Project")
    bad = tmp_path / "bad"
    bad.mkdir()
    (bad / "NotYaml.mat").write_text("Material: [unclosed\n  - {a: \n")
    (bad / "Ancient.mat").write_text(fx.UNITY4)
    (bad / "only").mkdir()
    (bad / "only" / "Spec.mat").write_text(fx.mat_pairs("Spec", shader_file_id=45))
    text_blend = tmp_path / "notes.blend"
    text_blend.write_text("my notes, not a .blend\n")
    real_blend = tmp_path / "mine.blend"
    real_blend.write_bytes(b"BLENDER-v502" + b"\0" * 64)
    before = {p: p.read_bytes() for p in (text_blend, real_blend)}
    snap = fx.snapshot(tmp_path)
    out = tmp_path / "new.blend"
    cases = [
        ([bad / "NotYaml.mat", "--out", out], "is not YAML"),
        ([bad / "Ancient.mat", "--out", out], "Unity 4's layout"),
        ([project, "--out", text_blend], "exists and is not a .blend file"),
        ([project, "--out", tmp_path / "notes.txt"], "is not a .blend file name"),
        ([project, "--out", real_blend], "exists; give --force"),
        ([project, "--out", project / "Assets" / "x.blend"], "lies inside the Unity folder"),
        ([bad / "only", "--out", out], "holds no material of Unity's built-in Standard"),
    ]
    for argv, message in cases:
        code, err = _run(["import-unity", *argv], capsys)
        assert code == 2, (argv, err)
        lines = err.strip().splitlines()
        assert len(lines) == 1 and message in lines[0], (argv, err)
    assert not out.exists()
    assert {p: p.read_bytes() for p in before} == before
    assert fx.snapshot(tmp_path) == snap


# ---------------------------------------------------------------------------------------
# Blender -> Unity files -> Blender


def _image(folder, name, pixels, colorspace):
    path = folder / f"{name}.png"
    path.write_bytes(fx.png_bytes(pixels))
    image = bpy.data.images.load(str(path))
    image.colorspace_settings.name = colorspace
    return image


def _grey(values, size=4):
    px = np.ones((size, size, 4))
    px[..., :3] = np.asarray(values, float).reshape(size, size, 1) / 255.0
    return px


def _render(scene, mat, path):
    scene.objects["Ball"].material_slots[0].material = mat
    scene.render.filepath = str(path)
    bpy.ops.render.render(write_still=True)
    return compare.read_image(path)


def test_blender_to_unity_to_blender(tmp_path):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    src = tmp_path / "src"
    src.mkdir()
    rng = np.random.default_rng(5)
    paint = np.ones((4, 4, 4))
    paint[..., :3] = rng.integers(20, 235, (4, 4, 3)) / 255.0
    normal = np.ones((4, 4, 4))
    normal[..., 0], normal[..., 1], normal[..., 2] = 150 / 255, 110 / 255, 230 / 255
    metal_values = rng.integers(0, 256, 16)
    rough_values = rng.integers(0, 256, 16)
    orig = materials.model_material(
        "Original",
        impl="nodes",
        options=ModelOptions(ibl="split_sum"),
        albedo_image=_image(src, "paint", paint, "sRGB"),
        normal_map=_image(src, "normal", normal, "Non-Color"),
        normal_strength=0.6,
    )
    nt, node = orig.node_tree, model_node.find(orig)
    model_node.set_defaults(node, ARTIST)
    metal = nt.nodes.new("ShaderNodeTexImage")
    metal.image = _image(src, "metal", _grey(metal_values), "Non-Color")
    nt.links.new(metal.outputs["Color"], model_node.surface_input(node, "metallic"))
    rough = nt.nodes.new("ShaderNodeTexImage")
    rough.image = _image(src, "rough", _grey(rough_values), "Non-Color")
    inv = nt.nodes.new("ShaderNodeMath")
    inv.operation = 'SUBTRACT'
    inv.inputs[0].default_value = 1.0
    nt.links.new(rough.outputs["Color"], inv.inputs[1])
    nt.links.new(inv.outputs[0], model_node.surface_input(node, "smoothness"))

    # the export's records -> Unity's files, through export_job's write (and its gate)
    from addon.jobs.export_job import write_export

    records, files_, notes = material_export.read_materials([orig])
    assert not notes
    assets = tmp_path / "Project" / "Assets"
    written = write_export(records, files_, "unity", assets, "trip")
    assert {p.name for p in written} >= {"Original.mat", "Original.mat.meta", "paint.png"}
    assert not (assets / "textures" / "metal.png").exists()  # replaced by the packed map

    found = unity_import_job.read_unity(tmp_path / "Project")
    assert not found.skipped and not found.warnings
    (back,), warnings = unity_import_job.build(found, "nodes")
    assert not warnings
    bnode = model_node.find(back)
    # values within 1/255: the same albedo file, the normal's strength, the packed R and A
    tex, _ = _linked(model_node.surface_input(bnode, "albedo"))
    assert tex.image.filepath.endswith("paint.png")
    nmap, _ = _linked(model_node.surface_input(bnode, "normal"))
    assert nmap.inputs["Strength"].default_value == pytest.approx(0.6, abs=1 / 255)
    split, _ = _linked(model_node.surface_input(bnode, "metallic"))
    packed_tex, _ = _linked(split.inputs["Color"])
    assert packed_tex.image.colorspace_settings.name == "Non-Color"
    assert packed_tex.image.filepath.endswith("Original_metallic_gloss.png")
    packed = np.array(packed_tex.image.pixels[:]).reshape(4, 4, 4)[::-1]  # rows top first
    assert packed[..., 0].ravel() == pytest.approx(metal_values / 255.0, abs=1 / 255)
    assert packed[..., 3].ravel() == pytest.approx(1 - rough_values / 255.0, abs=1 / 255)

    # a small Cycles render of each, the same scene and seed
    bpy.ops.mesh.primitive_uv_sphere_add(segments=32, ring_count=16)
    ball = bpy.context.object
    ball.name = "Ball"
    bpy.ops.object.shade_smooth()
    ball.data.materials.append(orig)
    bpy.ops.object.light_add(type='SUN', rotation=(0.6, 0.2, 0.4))
    bpy.context.object.data.energy = 3.0
    bpy.ops.object.camera_add(location=(0, -4, 0), rotation=(np.pi / 2, 0, 0))
    scene.camera = bpy.context.object
    world = bpy.data.worlds.new("World")
    scene.world = world
    world.color = (0.2, 0.2, 0.2)
    renderer.set_converging_cycles(scene, osl=False, samples=16, seed=1)
    scene.render.resolution_x = scene.render.resolution_y = 32
    scene.render.resolution_percentage = 100
    scene.render.image_settings.file_format = 'OPEN_EXR'
    scene.view_settings.view_transform = 'Standard'
    for m in (orig, back):
        light_sync.sync_material(m, scene)
    a = _render(scene, orig, tmp_path / "orig.exr")
    b = _render(scene, back, tmp_path / "back.exr")
    assert a.mean() > 0.01
    assert np.abs(a - b).mean() / np.abs(a).mean() <= 1e-3


def test_import_operator(addon, tmp_path):
    """File > Import > Unity Materials: the same import into the open file, from a folder."""
    root = fx.write_project(tmp_path / "Project")
    before = fx.snapshot(root)
    assert bpy.ops.ctlab.import_unity(directory=str(root)) == {'FINISHED'}
    names = {m.name for m in bpy.data.materials if model_node.find(m) is not None}
    assert {"Brick", "Old", "AlbedoAlpha", "Missing"} <= names
    assert not {"Spec", "Autodesk", "Toon"} & {m.name for m in bpy.data.materials}
    assert fx.snapshot(root) == before
    with pytest.raises(RuntimeError, match="is not YAML"):
        (tmp_path / "Bad.mat").write_text("Material: [unclosed\n")
        bpy.ops.ctlab.import_unity(filepath=str(tmp_path / "Bad.mat"))


def test_export_operator_round_trip(addon, tmp_path):
    """Export Cook-Torrance as Unity Materials (the panels' Unity button) writes what the
    command writes; the imported materials go back out to .mat files of the same values."""
    root = fx.write_project(tmp_path / "Project")
    assert bpy.ops.ctlab.import_unity(directory=str(root)) == {'FINISHED'}
    out = tmp_path / "Out"
    assert bpy.ops.ctlab.export_unity(directory=str(out)) == {'FINISHED'}
    found = unity_import_job.read_unity(out)
    back = {s.name: s for s in found.surfaces}
    first = {s.name: s for s in unity_import_job.read_unity(root).surfaces}
    assert set(back) == {"Brick", "Old", "AlbedoAlpha", "Missing"}, sorted(back)
    for name in ("Old", "Missing"):
        assert back[name].metallic == pytest.approx(first[name].metallic, abs=1 / 255)
        assert back[name].smoothness == pytest.approx(first[name].smoothness, abs=1 / 255)
    # Brick: _Color times _MainTex (a Mix), the packed map's R and A x _GlossMapScale 0.8
    # (Separate Color, Alpha, Multiply), the normal map of strength 0.5 and _MainTex's
    # tiling (a Mapping node) go back out as Unity's own properties and one packed map
    brick, orig = back["Brick"], first["Brick"]
    assert brick.albedo == pytest.approx(orig.albedo, abs=1 / 255)
    assert brick.albedo_map.path.endswith("albedo.png") and brick.albedo_map.srgb
    assert (brick.tiling, brick.offset) == ((2.0, 3.0), (0.25, 0.5))
    assert brick.normal_map is not None and brick.bump_scale == pytest.approx(0.5)
    assert brick.smoothness_from == "metallic_map" and brick.gloss_map_scale == 1.0
    assert not brick.metallic_map.srgb  # written decoded: linear
    metal = fx.metal_pixels()
    packed = _png(brick.metallic_map.path)
    decoded = np.vectorize(_srgb)(metal[..., 0])  # its .meta says sRGB: Unity decodes R
    assert packed[..., 0] == pytest.approx(decoded, abs=1 / 255)
    assert packed[..., 3] == pytest.approx(metal[..., 3] * 0.8, abs=1 / 255)
    # AlbedoAlpha: smoothness = _MainTex's A x 0.5, metallic = the metallic map's R
    aa = back["AlbedoAlpha"]
    assert aa.smoothness_from == "metallic_map" and aa.albedo_map is not None
    packed = _png(aa.metallic_map.path)
    assert packed[..., 0] == pytest.approx(decoded, abs=1 / 255)
    assert packed[..., 3] == pytest.approx(fx.albedo_alpha_pixels()[..., 3] * 0.5, abs=1 / 255)
    # the other formats carry the same shapes: MaterialX validates, glTF has the transform
    assert bpy.ops.ctlab.export_materialx(directory=str(tmp_path / "Mtlx")) == {'FINISHED'}
    from materialx_check import materialx_check

    checked = materialx_check([tmp_path / "Mtlx" / "Brick.mtlx"])
    assert checked[str(tmp_path / "Mtlx" / "Brick.mtlx")]["valid"], checked
    text = (tmp_path / "Mtlx" / "Brick.mtlx").read_text()
    assert 'type="vector2" value="2, 3"' in text and 'type="vector2" value="0.25, 0.5"' in text
    from addon.blender import material_export as me
    from addon.core.export import gltf

    mats = [bpy.data.materials["Brick"]]
    records, _, notes = me.read_materials(mats)
    assert not notes, notes
    doc = gltf.gltf_document(records)
    info = doc["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"]
    transform = info["extensions"]["KHR_texture_transform"]
    assert transform == {"offset": [0.25, 1 - 3 - 0.5], "scale": [2.0, 3.0]}
    assert doc["extensionsUsed"] == ["KHR_texture_transform"]
    with pytest.raises(RuntimeError, match="ctlab did not write"):
        (tmp_path / "Mine").mkdir()
        (tmp_path / "Mine" / "Brick.mat").write_text("mine\n")
        bpy.ops.ctlab.export_unity(directory=str(tmp_path / "Mine"))
    assert (tmp_path / "Mine" / "Brick.mat").read_text() == "mine\n"
