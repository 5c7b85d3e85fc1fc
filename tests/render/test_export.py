"""``ctlab export FILE.blend --format materialx|usd|gltf`` (addon/jobs/export_job.py, the model
as MaterialX in addon/core/export/) and its proof: every written .mtlx passes MaterialX's
own ``validate()`` (PyPI materialx, run in a child process without bpy: Blender's bundled
MaterialX lacks the OSL generator and the two would clash), MaterialX's OSL generator turns the
graph into OSL that Cycles compiles and renders equal to the model's ``scene`` transport for
the height-correlated Smith G, and for the other G and compensated energy the difference is
the directional albedo residual of docs/model.md's table, computed here by brute-force quadrature
(tests/reference_model.py), not by the code under test. The USD file is read back with USD's
own reader (Blender's bundled pxr). Bad input: one line, exit status 2, nothing written.

Mutation check (done once): color0 = albedo instead of mix(0.04, albedo, metallic) in
core/export/network.py made the Smith renders differ by 0.55 (peak 1.06; bound 1e-3 of it),
and the diffuse switch fixed to Burley made the Lambert case differ by 0.0041 (bound
0.0011)."""

import json
import subprocess
import sys
import textwrap

import bpy
import numpy as np
import pytest

from helpers import ROOT
from materialx_check import materialx_check
from reference_model import specular_albedo

from addon.blender import compat, model_node, osl_shader, renderer, scene_builder
from addon.core import compare
from addon.core.export import materialx, network
from addon.core.model import ModelOptions
from addon.core.settings import MatrixSettings, describe

CTLAB = [sys.executable, str(ROOT / "scripts" / "ctlab.py")]
SIZE, SAMPLES = 40, 32

BUILD = textwrap.dedent(r'''
    import os, sys
    sys.path.insert(0, sys.argv[1])
    import bpy
    from addon import blender  # noqa: F401
    from addon.blender import materials, model_node
    from addon.core.model import ModelOptions

    out = sys.argv[2]

    def obj(name, mat):
        bpy.ops.mesh.primitive_cube_add()
        o = bpy.context.object
        o.name = name
        o.data.materials.append(mat)

    def image(name, value, colorspace):
        img = bpy.data.images.new(name, 4, 4)
        img.pixels = [value, value, value, 1.0] * 16
        img.filepath_raw = os.path.join(out, name + ".png")
        img.file_format = 'PNG'
        img.save()
        img.colorspace_settings.name = colorspace
        return img

    bpy.ops.wm.read_factory_settings(use_empty=True)
    smith = ModelOptions(light_transport="scene", g_model="smith_ggx_correlated")
    obj("Sphere", materials.model_material("CT Smith", impl="osl", options=smith,
        albedo=(0.9, 0.5, 0.3), metallic=0.4, smoothness=0.6))
    m = materials.model_material("CT Textured", impl="nodes", options=ModelOptions(
        light_transport="scene", diffuse_model="lambert", ibl="split_sum"),
        albedo_image=image("paint", 0.5, "sRGB"), metallic=0.0, smoothness=0.3)
    nt, node = m.node_tree, model_node.find(m)
    rough = nt.nodes.new("ShaderNodeTexImage")
    rough.image = image("rough", 0.7, "Non-Color")
    inv = nt.nodes.new("ShaderNodeMath")
    inv.operation = 'SUBTRACT'
    inv.inputs[0].default_value = 1.0
    nt.links.new(rough.outputs["Color"], inv.inputs[1])
    nt.links.new(inv.outputs[0], model_node.surface_input(node, "smoothness"))
    nmap = nt.nodes.new("ShaderNodeNormalMap")
    nmap.inputs["Strength"].default_value = 0.5
    ntex = nt.nodes.new("ShaderNodeTexImage")
    ntex.image = image("normal", 0.5, "Non-Color")
    ntex.image.pack()  # written out from the .blend's data
    os.remove(os.path.join(out, "normal.png"))
    nt.links.new(ntex.outputs["Color"], nmap.inputs["Color"])
    nt.links.new(nmap.outputs["Normal"], model_node.surface_input(node, "normal"))
    obj("Box", m)
    obj("Pot", materials.model_material("CT Cook-Torrance", impl="osl"))
    bpy.ops.wm.save_as_mainfile(filepath=os.path.join(out, "export.blend"), compress=False)
    rough.image.filepath = os.path.join(out, "gone.png")
    bpy.ops.wm.save_as_mainfile(filepath=os.path.join(out, "missing.blend"), compress=False)
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.mesh.primitive_cube_add()
    bpy.context.object.data.materials.append(materials.principled_material("Floor"))
    bpy.ops.wm.save_as_mainfile(filepath=os.path.join(out, "principled.blend"))
''')


@pytest.fixture(scope="module")
def blends(tmp_path_factory):
    folder = tmp_path_factory.mktemp("blends")
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


def test_export_materialx_validates(blends, tmp_path):
    """One .mtlx per Cook-Torrance material, each valid for MaterialX 1.39.5 and turned into
    OSL by its generator; the textures copied with their colour spaces (sRGB albedo, raw
    roughness through 1 - x, a packed normal map of strength 0.5, written out from the
    .blend); nothing written outside --out."""
    out = tmp_path / "mtlx"
    before = {p: p.stat().st_mtime_ns for p in blends.iterdir()}
    run = ctlab("export", blends / "export.blend", "--format", "materialx", "--out", out)
    assert run.returncode == 0, run.stderr
    # nothing written beside the inputs (no .blend1, no texture touched), only --out made
    assert {p: p.stat().st_mtime_ns for p in blends.iterdir()} == before
    assert [p.name for p in tmp_path.iterdir()] == ["mtlx"]
    names = sorted(p.name for p in out.glob("*.mtlx"))
    assert names == ["CT_Cook_Torrance.mtlx", "CT_Smith.mtlx", "CT_Textured.mtlx"], names
    assert sorted(p.name for p in (out / "textures").iterdir()) == [
        "normal.png",
        "paint.png",
        "rough.png",
    ]
    checked = materialx_check(sorted(out.glob("*.mtlx")))
    for path, r in checked.items():
        assert r["valid"], (path, r["message"])
        assert r["version"] == "1.39.5"
        assert "generalized_schlick_bsdf" in r["osl"] or "mx_generalized_schlick" in r["osl"]
    text = (out / "CT_Textured.mtlx").read_text()
    assert 'colorspace="srgb_texture"' in text and "textures/paint.png" in text
    assert "normalmap" in text and "smoothness_invert" in text
    assert compare.read_image(out / "textures" / "normal.png")[..., 0] == pytest.approx(
        np.full((4, 4), 128 / 255), abs=1e-6
    )
    assert '<input name="diffuse_lambert" type="integer" value="1"' in text
    assert "CT Cook-Torrance: G cook_torrance (written as height-correlated Smith)" in run.stdout


def test_export_usd_reads_back(blends, tmp_path):
    """The USD layer passes USD's own compliance checker and opens in its reader (Blender's
    pxr): each object's prim is bound to its material, whose mtlx:surface output is
    MaterialX's surface node fed by generalized_schlick_bsdf with the material's values."""
    out = tmp_path / "usd"
    run = ctlab("export", blends / "export.blend", "--format", "usd", "--out", out)
    assert run.returncode == 0, run.stderr
    from addon.blender.compat import bundled_module

    bundled_module("pxr")
    from pxr import Usd, UsdShade, UsdUtils

    checker = UsdUtils.ComplianceChecker(rootPackageOnly=False, skipVariants=False)
    checker.CheckCompliance(str(out / "export.usda"))
    assert not checker.GetErrors() and not checker.GetFailedChecks(), (
        checker.GetErrors(),
        checker.GetFailedChecks(),
    )
    stage = Usd.Stage.Open(str(out / "export.usda"))
    assert stage is not None
    bound = UsdShade.MaterialBindingAPI(stage.GetPrimAtPath("/Objects/Sphere"))
    material = bound.ComputeBoundMaterial()[0]
    assert material.GetPath().pathString == "/Materials/CT_Smith"
    surface, _, _ = material.ComputeSurfaceSource("mtlx")
    assert surface.GetShaderId() == "ND_surface"
    spec = UsdShade.Shader(stage.GetPrimAtPath("/Materials/CT_Smith/specular"))
    assert spec.GetShaderId() == "ND_generalized_schlick_bsdf"
    mix = UsdShade.Shader(stage.GetPrimAtPath("/Materials/CT_Smith/spec_color"))
    fg = mix.GetInput("fg").GetConnectedSources()[0][0].source.GetPath().pathString
    assert fg == "/Materials/CT_Smith/albedo_c"
    metallic = UsdShade.Shader(stage.GetPrimAtPath("/Materials/CT_Smith/metallic_c"))
    assert metallic.GetInput("in").Get() == pytest.approx(0.4)
    albedo = UsdShade.Shader(stage.GetPrimAtPath("/Materials/CT_Smith/albedo_c"))
    assert tuple(albedo.GetInput("in").Get()) == pytest.approx((0.9, 0.5, 0.3))
    tex = UsdShade.Shader(stage.GetPrimAtPath("/Materials/CT_Textured/albedo_image"))
    assert tex.GetInput("file").Get().path == "textures/paint.png"


def test_export_gltf(blends, tmp_path):
    """glTF: baseColorFactor = albedo, metallicFactor, roughnessFactor = 1 - smoothness, the
    albedo and normal textures, metallic and roughness packed into one image as glTF wants
    them (G roughness, B metallic); what glTF cannot carry listed in extras; every file under
    textures/ referenced by the .gltf (the raw roughness map, packed, is not copied: copying
    every map, as before, failed here on rough.png)."""
    out = tmp_path / "gltf"
    run = ctlab("export", blends / "export.blend", "--format", "gltf", "--out", out)
    assert run.returncode == 0, run.stderr
    doc = json.loads((out / "export.gltf").read_text())
    assert doc["asset"]["version"] == "2.0"
    by_name = {m["name"]: m for m in doc["materials"]}
    smith = by_name["CT Smith"]["pbrMetallicRoughness"]
    assert smith["baseColorFactor"] == pytest.approx([0.9, 0.5, 0.3, 1.0])
    assert smith["metallicFactor"] == pytest.approx(0.4)
    assert smith["roughnessFactor"] == pytest.approx(0.4)
    tex = by_name["CT Textured"]
    base = doc["textures"][tex["pbrMetallicRoughness"]["baseColorTexture"]["index"]]["source"]
    assert doc["images"][base]["uri"] == "textures/paint.png"
    assert tex["normalTexture"]["scale"] == pytest.approx(0.5)
    # the roughness map (0.7, wired through 1 - x) in G of the packed image, metallic 1 in B
    # (its factor 0 carries the value), R unused
    rough = tex["pbrMetallicRoughness"]
    assert rough["roughnessFactor"] == 1.0 and rough["metallicFactor"] == 0.0
    uri = doc["images"][doc["textures"][rough["metallicRoughnessTexture"]["index"]]["source"]]
    pixels = compare.read_image(out / uri["uri"])
    assert pixels[..., 1] == pytest.approx(np.full((4, 4), 179 / 255), abs=1e-6)
    assert pixels[..., 2] == pytest.approx(np.ones((4, 4)))
    assert "Burley (Disney) diffuse" in " ".join(
        by_name["CT Smith"]["extras"]["cook_torrance_lab"]["not_carried"]
    )
    # only what the .gltf references: no stray raw map beside the packed image
    uris = {img["uri"] for img in doc["images"]}
    on_disk = {p.relative_to(out).as_posix() for p in (out / "textures").rglob("*")}
    assert on_disk <= uris, on_disk - uris
    assert sorted(p.name for p in out.iterdir()) == [
        ".ctlab-written.json",  # the write gate's record (core/gate.py)
        "export.gltf",
        "textures",
    ]


def test_export_gltf_packs_a_map_from_the_blend(tmp_path):
    """A roughness map packed in the .blend (bytes, no file) is read through a private
    temporary file into glTF's metallic-roughness image (G = the map, wired through 1 - x),
    and is not written itself: the folder holds the .gltf and the packed image only, even
    with no other texture to make textures/ first."""
    from addon.blender.material_export import TextureFile
    from addon.jobs.export_job import write_export

    src = tmp_path / "r.png"
    compare.write_png(src, np.full((2, 3, 3), 0.7))
    mat = network.Material(
        "R", textures={"smoothness": network.Texture("textures/r.png", invert=True)}
    )
    files = [TextureFile("textures/r.png", data=src.read_bytes())]
    out = tmp_path / "out"
    written = write_export([mat], files, "gltf", out, "x")
    names = sorted(
        p.relative_to(out).as_posix()
        for p in out.rglob("*")
        if p.is_file() and p.name != ".ctlab-written.json"  # the write gate's record
    )
    assert names == ["textures/R_metallic_roughness.png", "x.gltf"], names
    assert sorted(p.relative_to(out).as_posix() for p in written) == names
    pixels = compare.read_image(out / "textures" / "R_metallic_roughness.png")
    assert pixels[..., 1] == pytest.approx(np.full((2, 3), 179 / 255), abs=1e-6)
    assert pixels[..., 2] == pytest.approx(np.ones((2, 3)))


@pytest.mark.parametrize(
    "blend,args,message",
    [
        ("principled.blend", ("--format", "materialx"), "has no Cook-Torrance material"),
        ("missing.blend", ("--format", "usd"), "its file is missing"),
        ("export.blend", ("--format", "obj"), "invalid choice"),
    ],
)
def test_export_bad_input(blends, tmp_path, blend, args, message):
    """A file with no Cook-Torrance material, a texture whose file is gone, an unknown format:
    one line, exit status 2, nothing written."""
    out = tmp_path / "out"
    run = ctlab("export", blends / blend, *args, "--out", out)
    assert run.returncode == 2 and message in run.stderr, run.stderr
    assert len(run.stderr.strip().splitlines()) == 1, run.stderr
    assert not out.exists()


def test_export_unwritable_out(blends, tmp_path):
    """An --out that cannot be written (below a file): one line, exit 2."""
    blocker = tmp_path / "file"
    blocker.write_text("x")
    run = ctlab("export", blends / "export.blend", "--format", "gltf", "--out", blocker / "out")
    assert run.returncode == 2, run.stderr
    assert len(run.stderr.strip().splitlines()) == 1, run.stderr
    assert blocker.read_text() == "x"


# ---------------------------------------------------------------------------------------
# The equivalence renders: five spheres in a row (one per case, each its own material),
# rendered once with the model's scene transport and once with MaterialX's OSL


# (name, G, diffuse, energy, albedo, metallic, smoothness): Smith's G, where the graph is
# the model, on a coloured half-metal with either diffuse; then white metals (F = 1) for the
# residual of the other G and of compensated energy.
CASES = (
    ("smith_disney", "smith_ggx_correlated", "disney", "none", (0.9, 0.5, 0.3), 0.4, 0.6),
    ("smith_lambert", "smith_ggx_correlated", "lambert", "none", (0.9, 0.5, 0.3), 0.4, 0.6),
    ("cook_torrance", "cook_torrance", "disney", "none", (1.0, 1.0, 1.0), 1.0, 0.1),
    ("unity", "unity_smith_joint", "disney", "none", (1.0, 1.0, 1.0), 1.0, 0.5),
    ("compensated", "smith_ggx_correlated", "disney", "compensated", (1.0, 1.0, 1.0), 1.0, 0.3),
)
MASK_FRACTION = 0.9  # of each sphere's radius


@pytest.fixture(scope="module")
def renders(uniform_hdri, tmp_path_factory):
    """One row of spheres under a uniform white world (radiance 1), no Sun, an orthographic
    camera, spheres hidden from each other's rays: each sees the world alone. Rendered with
    each case's model material (scene transport), then with each case's MaterialX-generated
    OSL, same samples and seed. Returns {case: (model, materialx, sphere mask)}."""
    folder = tmp_path_factory.mktemp("equivalence")
    bpy.ops.wm.read_factory_settings(use_empty=True)
    s = MatrixSettings(
        rows=1,
        cols=len(CASES),
        width=SIZE * len(CASES),
        height=SIZE,
        hdri=uniform_hdri,
        sun_strength=0.0,
        mutual_shadows=False,
        model=ModelOptions(light_transport="scene"),
    )
    scene = bpy.context.scene
    scene_builder.build_matrix(scene, s, scene_builder.environment_files(s))
    shared = next(m for m in bpy.data.materials if m.get(scene_builder.TAG))
    spheres = {
        o["ctlab_col"]: o for o in scene.objects if o.get(scene_builder.TAG) and o.type == 'MESH'
    }
    cases = [
        network.Material(name, albedo, metallic, smoothness, g_model=g, diffuse_model=d, energy=e)
        for name, g, d, e, albedo, metallic, smoothness in CASES
    ]
    paths = []
    for col, mat in enumerate(cases):
        obj = spheres[col]
        obj["ctlab_albedo"], obj["ctlab_metallic"] = list(mat.albedo), mat.metallic
        obj["ctlab_smoothness"] = mat.smoothness
        model = shared.copy()
        model_node.set_options(
            model_node.find(model),
            s.model_options(
                light_transport="scene",
                g_model=mat.g_model,
                diffuse_model=mat.diffuse_model,
                energy=mat.energy,
            ),
        )
        obj.material_slots[0].link = 'OBJECT'
        obj.material_slots[0].material = model
        paths.append(folder / f"{mat.name}.mtlx")
        paths[-1].write_text(materialx.mtlx_document(mat))
    renderer.configure(scene, "osl", "full", SAMPLES, path_traced=True)
    renderer.render(scene, folder / "model", dict(describe(s, s.hdri)))
    generated = materialx_check(paths)
    for col, path in enumerate(paths):
        assert generated[str(path)]["valid"], generated[str(path)]["message"]
        src = folder / f"{cases[col].name}.osl"
        src.write_text(generated[str(path)]["osl"])
        mx_mat = bpy.data.materials.new("MaterialX " + cases[col].name)
        compat.use_nodes(mx_mat)
        nt = mx_mat.node_tree
        nt.nodes.clear()
        script = nt.nodes.new("ShaderNodeScript")
        osl_shader.compile_script_node(script, src, "mtlx " + cases[col].name, output="out")
        output = nt.nodes.new("ShaderNodeOutputMaterial")
        nt.links.new(script.outputs["out"], output.inputs["Surface"])
        spheres[col].material_slots[0].material = mx_mat
    renderer.render(scene, folder / "mtlx", dict(describe(s, s.hdri)))
    a, _, desc = compare.load_render(folder / "model")
    b, _, _ = compare.load_render(folder / "mtlx")
    cells = {c["col"]: c for c in desc["cells"]}
    return {
        mat.name: (mat, a, b, compare.cell_mask(a.shape[:2], cells[col], MASK_FRACTION))
        for col, mat in enumerate(cases)
    }


@pytest.mark.parametrize("case", ["smith_disney", "smith_lambert"])
def test_materialx_osl_renders_the_model_for_smith_g(renders, case):
    """Smith G, energy none: MaterialX's graph is the model. The MaterialX-generated OSL and
    the model's scene transport, path traced with the same samples and seed, agree at every
    pixel of the sphere within 1e-3 of the image's peak."""
    mat, a, b, mask = renders[case]
    assert np.isfinite(b).all() and b[mask].mean() > 0.05
    peak = float(a.max())
    diff = float(np.abs(a[mask] - b[mask]).max())
    print(f"{case}: max |model - MaterialX| {diff:.2e} of peak {peak:.3f}")
    assert diff <= 1e-3 * peak


@pytest.mark.parametrize("case", ["cook_torrance", "unity", "compensated"])
def test_materialx_osl_residual_equals_the_table(renders, case):
    """The other G and compensated energy (a white metal, F = 1, under a uniform world): the
    exported graph is Smith's single-scattering lobe, so the model minus MaterialX is the
    directional albedo residual of docs/model.md's table, E_model(mu) - E_Smith(mu)
    (E_model = 1 when compensated: with F = 1 the compensated lobe reflects everything).
    Over the sphere's disk (orthographic: the pixels weigh mu as 2 mu dmu over
    mu >= sqrt(1 - 0.9^2)) the mean measured difference equals the mean of that residual,
    by brute-force quadrature of the closed forms (tests/reference_model.py), within 0.006
    (the noise of 32 samples; the residuals are 0.05 to 0.3)."""
    mat, a, b, mask = renders[case]
    measured = float((a[mask] - b[mask]).mean())
    k = MASK_FRACTION
    mu0 = np.sqrt(1 - k * k)
    n = 12
    mus = mu0 + (1 - mu0) * (np.arange(n) + 0.5) / n
    one = np.ones(3)

    def e(mu, g):
        return specular_albedo(mu, one, 1.0, mat.smoothness, g, n_theta=300, n_phi=150)[0]

    residual = np.array(
        [
            (1.0 if mat.energy == "compensated" else e(m, mat.g_model))
            - e(m, "smith_ggx_correlated")
            for m in mus
        ]
    )
    expected = float(np.sum(residual * 2 * mus) * (1 - mu0) / n / (k * k))
    print(f"{case} residual: measured {measured:.4f}, quadrature {expected:.4f}")
    assert abs(expected) > 0.04  # resolved: well above the tolerance
    assert abs(measured - expected) < 0.006, (measured, expected)


def test_export_operator_writes_the_active_or_every_material(addon, blends, tmp_path):
    """Export Cook-Torrance as MaterialX (ctlab.export_materialx) writes what the command
    writes, from the open file: every model material, or the active one; without a folder or
    with a non-model active material it reports one error and writes nothing."""
    bpy.ops.wm.open_mainfile(filepath=str(blends / "export.blend"), load_ui=False)
    out = tmp_path / "all"
    assert bpy.ops.ctlab.export_materialx(directory=str(out)) == {'FINISHED'}
    assert sorted(p.name for p in out.glob("*.mtlx")) == [
        "CT_Cook_Torrance.mtlx",
        "CT_Smith.mtlx",
        "CT_Textured.mtlx",
    ]
    assert materialx_check([out / "CT_Textured.mtlx"])[str(out / "CT_Textured.mtlx")]["valid"]
    box = bpy.data.objects["Box"]
    bpy.context.view_layer.objects.active = box
    one = tmp_path / "one"
    assert bpy.ops.ctlab.export_materialx(directory=str(one), scope='ACTIVE') == {'FINISHED'}
    assert [p.name for p in one.glob("*.mtlx")] == ["CT_Textured.mtlx"]
    with pytest.raises(RuntimeError, match="choose a folder"):
        bpy.ops.ctlab.export_materialx(directory="")
    box.material_slots[0].material = bpy.data.materials.new("Plain")
    none = tmp_path / "none"
    with pytest.raises(RuntimeError, match="does not use the Cook-Torrance model"):
        bpy.ops.ctlab.export_materialx(directory=str(none), scope='ACTIVE')
    assert not none.exists()
