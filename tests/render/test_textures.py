"""The seed's textured sphere matrix (core/textures.py, ``--albedo-texture``, ``--normal-map``,
``--textured``): the textures reach every view and both implementations, the term views
shade the perturbed normal (checked against the model's formulas computed independently in
numpy from the rendered normal view, tests/reference_model.py), a flipped-green normal map
mirrors the bevels' vertical tilt and keeps their horizontal one, and bad images are one line
before anything is written. Renders are small (3x3, 96 px) at pixel centres."""

import json
import subprocess

import bpy
import numpy as np
import pytest

from helpers import CTLAB, render, sphere_pixels
from reference_model import terms

from addon.core import compare, textures
from addon.core.hdri import write_float_exr

VIEWS = ("D", "F", "G", "NdotL", "NdotV", "NdotH", "VdotH", "specular_brdf", "diffuse_brdf")
KW = dict(grid=(3, 3), size=96, sun_to_light=(-0.3, -0.6, 0.74))

# Blender 4.5's Cycles with OSL on reads an Image Texture node through OSL's texture
# system, which filters differently from SVM's lookup (seen: normals up to 0.36 apart, the
# full render mean dE 4.5 between the OSL shader and the node group); 5.2 reads both alike.
SAME_TEXELS = pytest.mark.skipif(
    bpy.app.version < (5, 0, 0),
    reason="4.5: Image Texture nodes under OSL filter otherwise than under SVM",
)

CASES = {
    "texture-missing": "test_bad_textures_are_one_line_and_nothing_is_written",
    "texture-not-image": "test_bad_textures_are_one_line_and_nothing_is_written",
    "texture-nan": "test_bad_textures_are_one_line_and_nothing_is_written",
    "texture-too-large": "test_bad_textures_are_one_line_and_nothing_is_written",
    "normal-map-not-normal": "test_a_map_that_is_not_a_normal_map_is_warned_about",
}


def _inside(scene):
    m = np.zeros((scene["height"], scene["width"]), bool)
    for cell in scene["cells"]:
        m |= sphere_pixels(scene, cell)
    return m


@pytest.fixture(scope="module")
def normal_mapped(tmp_path_factory):
    """Each implementation's normal and term views with the shipped normal map, and the
    plain normal view."""
    base = tmp_path_factory.mktemp("textured")
    out = {}
    for shader in ("osl", "nodes"):
        kw = dict(KW, ibl="split_sum") if shader == "nodes" else KW
        out[shader] = render(
            base / shader,
            shader=shader,
            view=("normal", "albedo", *VIEWS),
            normal_map=str(textures.SEED_NORMAL),
            **kw,
        )
    out["plain"] = render(base / "plain", view=("normal",), **KW)
    return out


@SAME_TEXELS
def test_a_normal_map_bends_the_normal_view(normal_mapped):
    """The normal view is the perturbed normal: unit length, and away from the sphere's own
    normal on the bricks' bevels (at least a tenth of the pixels by more than 5 degrees),
    the same in both implementations."""
    images, scene = normal_mapped["osl"]
    plain = normal_mapped["plain"][0]["normal"]
    inside = _inside(scene)
    n = images["normal"][inside]
    assert np.allclose(np.linalg.norm(n, axis=1), 1.0, atol=1e-4)
    angle = np.degrees(np.arccos(np.clip((n * plain[inside]).sum(1), -1, 1)))
    assert (angle > 5).mean() > 0.1, (angle > 5).mean()
    assert np.abs(normal_mapped["nodes"][0]["normal"][inside] - n).max() < 1e-4


@pytest.mark.parametrize("shader", ["osl", "nodes"])
@pytest.mark.parametrize("view", VIEWS)
def test_term_views_shade_the_perturbed_normal(normal_mapped, shader, view):
    """Each term view equals the model's formula evaluated on the rendered (perturbed)
    normal, not on the sphere's: D, F, G, the dot products and both BRDFs change with the
    map."""
    images, scene = normal_mapped[shader]
    inside = _inside(scene)
    albedo = np.zeros(inside.shape + (3,))
    metallic, smooth = np.zeros(inside.shape), np.zeros(inside.shape)
    for cell in scene["cells"]:
        m = sphere_pixels(scene, cell)
        albedo[m], metallic[m], smooth[m] = cell["albedo"], cell["metallic"], cell["smoothness"]
    ref = terms(
        images["normal"].astype(np.float64),
        scene["to_camera"],
        scene["sun"]["to_light"],
        albedo,
        metallic,
        smooth,
    )
    want = ref[view]
    want = np.broadcast_to(want[..., None] if want.ndim == 2 else want, images[view].shape)
    got, want = images[view][inside].astype(np.float64), want[inside]
    tol = np.maximum(2e-4 * np.abs(want), 2e-6)
    if view in ("D", "specular_brdf"):  # D's conditioning near its peak (test_term_views)
        alpha, nh = ref["alpha"][inside], ref["NdotH"][inside]
        cond = 4 * nh**2 * np.abs(alpha**2 - 1) / (nh**2 * (alpha**2 - 1) + 1) * 3e-7
        tol = np.maximum(tol, (cond[:, None] if got.ndim == 2 else cond) * np.abs(want))
    bad = np.abs(got - want) > tol
    assert bad.mean() < 1e-3, f"{view}: {int(bad.sum())} of {bad.size} values differ"
    plain_ref = terms(
        normal_mapped["plain"][0]["normal"].astype(np.float64),
        scene["to_camera"],
        scene["sun"]["to_light"],
        albedo,
        metallic,
        smooth,
    )[view]
    plain_ref = np.broadcast_to(
        plain_ref[..., None] if plain_ref.ndim == 2 else plain_ref, images[view].shape
    )[inside]
    if view not in ("F", "VdotH"):  # v.h and F(v.h) do not depend on the normal
        assert np.abs(got - plain_ref).max() > 1e-3  # the map changed the view


@SAME_TEXELS
def test_an_albedo_texture_reaches_both_implementations_and_principled(tmp_path):
    """The albedo view with the shipped albedo texture: the same in the OSL shader and the
    node group, varying across each sphere as the bricks do (not the constant albedo), and
    Principled's render with the same texture differs from its plain render."""
    tex = dict(KW, albedo_texture=str(textures.SEED_ALBEDO))
    osl, scene = render(tmp_path / "osl", view=("albedo",), **tex)
    nodes, _ = render(tmp_path / "nodes", shader="nodes", ibl="split_sum", view=("albedo",), **tex)
    inside = _inside(scene)
    a = osl["albedo"][inside]
    assert np.abs(nodes["albedo"][inside] - a).max() < 1e-4
    assert a.std(axis=0).min() > 0.02  # bricks and mortar, not one colour
    assert np.abs(a - np.array(scene["cells"][0]["albedo"])).mean() > 0.05
    p_tex, _ = render(tmp_path / "p", shader="principled", samples=4, **tex)
    p_plain, _ = render(tmp_path / "pp", shader="principled", samples=4, **KW)
    assert np.abs(p_tex[inside] - p_plain[inside]).mean() > 0.02


@SAME_TEXELS
def test_node_group_equals_osl_with_textures(tmp_path):
    """The full render (lab transport, split-sum) with both textures: node group = OSL
    shader, mean CIEDE2000 <= 0.1 (as on plain spheres)."""
    tex = dict(
        KW,
        ibl="split_sum",
        albedo_texture=str(textures.SEED_ALBEDO),
        normal_map=str(textures.SEED_NORMAL),
    )
    for shader in ("osl", "nodes"):
        render(tmp_path / shader, shader=shader, samples=4, **tex)
    result = compare.compare(tmp_path / "osl", tmp_path / "nodes", tmp_path / "cmp")
    assert result["overall"]["ciede2000_mean"] <= 0.1, result["overall"]


def test_a_flipped_green_normal_map_mirrors_the_vertical_tilt(tmp_path):
    """A DirectX-convention map (green down) is read as OpenGL's: its bevels' vertical tilt
    comes out mirrored (the change of the normal's world z against the sphere's own is
    anticorrelated with the right map's), the horizontal one kept (x correlated): a
    visibly different result, as docs/usage.md says."""
    flipped = tmp_path / "flipped.png"
    rgb = compare.read_image(textures.SEED_NORMAL)
    rgb[..., 1] = 1.0 - rgb[..., 1]
    compare.write_png(flipped, rgb)
    right, scene = render(
        tmp_path / "r", view=("normal",), normal_map=str(textures.SEED_NORMAL), **KW
    )
    wrong, _ = render(tmp_path / "w", view=("normal",), normal_map=str(flipped), **KW)
    plain, _ = render(tmp_path / "p", view=("normal",), **KW)
    inside = _inside(scene)
    d_right = right["normal"][inside] - plain["normal"][inside]
    d_wrong = wrong["normal"][inside] - plain["normal"][inside]
    assert np.corrcoef(d_right[:, 2], d_wrong[:, 2])[0, 1] < -0.5
    assert np.corrcoef(d_right[:, 0], d_wrong[:, 0])[0, 1] > 0.5


def _ctlab(*args):
    return subprocess.run([*CTLAB, *map(str, args)], capture_output=True, text=True, timeout=600)


def test_bad_textures_are_one_line_and_nothing_is_written(tmp_path):
    """Missing, not an image, NaN-holding, more than 8192 a side: exit 2, one line naming
    the file, --out never made. A non-square, non-power-of-two image is fine."""
    text = tmp_path / "notes.png"
    text.write_text("not an image")
    nan = tmp_path / "nan.exr"
    px = np.ones((4, 6, 3), np.float32)
    px[1, 2, 0] = np.nan
    write_float_exr(nan, px)
    wide = tmp_path / "wide.exr"
    write_float_exr(wide, np.ones((1, textures.MAX_SIDE + 1, 3), np.float32))
    cases = {
        "missing": (["--albedo-texture", tmp_path / "gone.png"], "albedo texture not found"),
        "not-image": (["--normal-map", text], "normal map unreadable"),
        "nan": (["--albedo-texture", nan], "NaN/Inf"),
        "too-large": (["--normal-map", wide], "at most 8192 a side"),
    }
    for name, (args, expect) in cases.items():
        out = tmp_path / f"out-{name}"
        run = _ctlab(
            "render",
            "--shader",
            "osl",
            "--grid",
            "1x1",
            "--size",
            "32",
            "--samples",
            "1",
            *args,
            "--out",
            out,
        )
        lines = [line for line in run.stderr.splitlines() if line.strip()]
        assert run.returncode == 2 and len(lines) == 1, (name, run.stderr)
        assert expect in lines[0], (name, lines[0])
        assert not out.exists(), name
    odd = tmp_path / "odd.png"
    compare.write_png(odd, np.full((37, 53, 3), 0.5))
    run = _ctlab(
        "render", "--shader", "osl", "--grid", "1x1", "--size", "32", "--samples", "1",
        "--albedo-texture", odd, "--out", tmp_path / "odd",
    )  # fmt: skip
    assert run.returncode == 0, run.stderr


def test_a_map_that_is_not_a_normal_map_is_warned_about(tmp_path):
    """An albedo image given as the normal map (mean blue well under 0.5): one warning line,
    the job still runs (it may be a deliberate experiment)."""
    run = _ctlab(
        "render", "--shader", "osl", "--grid", "1x1", "--size", "32", "--samples", "1",
        "--normal-map", textures.SEED_ALBEDO, "--out", tmp_path / "o",
    )  # fmt: skip
    assert run.returncode == 0, run.stderr
    warnings = [line for line in run.stderr.splitlines() if "probably not a normal map" in line]
    assert len(warnings) == 1, run.stderr


def test_the_textured_job_reports_its_textures(tmp_path):
    """``matrix --textured`` (a tiny grid): exit 0, the report says textures are on and
    shows both images, scene.json names them, and the render differs from the plain job's."""
    small = ["--grid", "2x2", "--size", "48", "--samples", "2"]
    run = _ctlab("matrix", *small, "--textured", "--out", tmp_path / "t")
    assert run.returncode == 0, run.stderr[-2000:]
    page = (tmp_path / "t" / "report.html").read_text()
    assert "Textures: on" in page and page.count("data:image/png;base64,") == 2
    assert "seed_albedo.png" in page and "seed_normal.png" in page
    scene = json.loads((tmp_path / "t" / "cook_torrance" / "scene.json").read_text())
    assert scene["textures"]["normal_map"].endswith("seed_normal.png")
    run = _ctlab("render", "--shader", "osl", *small, "--out", tmp_path / "plain")
    assert run.returncode == 0, run.stderr
    a = compare.read_image(tmp_path / "t" / "cook_torrance" / "render.exr")
    b = compare.read_image(tmp_path / "plain" / "render.exr")
    assert np.abs(a - b).mean() > 0.01


def test_the_sphere_matrix_operator_puts_the_seed_textures_on(addon):
    """Build Sphere Matrix with Seed Textures: the matrix material reads the shipped albedo
    texture and, through a Normal Map node, the shipped normal map into the model's normal;
    an unreadable texture is one error report and builds nothing."""
    import bpy

    from addon.blender import model_node, scene_builder

    result = bpy.ops.ctlab.build_sphere_matrix(
        rows=2, cols=2, resolution=32, shader="nodes", ibl="split_sum", seed_textures=True
    )
    assert result == {'FINISHED'}
    mat = next(m for m in bpy.data.materials if m.get(scene_builder.TAG))
    images = {n.image.filepath for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeTexImage"}
    assert images == {str(textures.SEED_ALBEDO), str(textures.SEED_NORMAL)}
    normal = model_node.surface_input(model_node.find(mat), "normal")
    assert normal.is_linked and normal.links[0].from_node.bl_idname == "ShaderNodeNormalMap"
    uv = [
        o.data.uv_layers for o in bpy.data.objects if o.get(scene_builder.TAG) and o.type == 'MESH'
    ]
    assert uv and all(len(layers) == 1 for layers in uv)
    # twice around (u 0..2), once pole to pole (v 0..1), in the mesh: no Mapping node to pay
    coords = np.array([d.uv[:] for d in uv[0][0].data])
    assert coords[:, 0].min() == pytest.approx(0, abs=1e-6)
    assert coords[:, 0].max() == pytest.approx(2, abs=1e-6)
    assert coords[:, 1].min() == pytest.approx(0, abs=1e-6)
    assert coords[:, 1].max() == pytest.approx(1, abs=1e-6)
    assert not any(n.bl_idname == "ShaderNodeMapping" for n in mat.node_tree.nodes)
    with pytest.raises(RuntimeError, match="normal map not found"):
        bpy.ops.ctlab.build_sphere_matrix(rows=2, cols=2, resolution=32, normal_map="/gone.png")


def test_a_normal_map_feeds_the_osl_shader_without_derivatives(tmp_path):
    """Under OSL the nodes feeding the model's Normal would run with derivatives (for its
    shadow rays' differentials), a normal map's at about twice its cost: where other nodes
    than the geometry's normal feed the input, model_node.set_normal_derivatives sets the
    shader's Normal Derivatives to 0, and the shader drops them through a message
    (osl/cook_torrance.osl without_derivatives). The values stay the same: a normal-mapped
    sphere lit by the Sun renders equal with the input at 0 and at 1 (bit for bit on 5.2,
    within 2e-6 on 4.5), and differs from the plain sphere. Mutation checks: a message read
    back as another type than it was set fails silently and renders a zero normal (the
    equality fails); without set_normal_derivatives the input stays 1."""
    from helpers import SUN_LIT, render_still, sun_lit_sphere

    from addon.blender import materials, model_node
    from addon.core.model import Lighting, ModelOptions

    scene, sphere = sun_lit_sphere(48)
    lighting = Lighting(**SUN_LIT)
    image = bpy.data.images.load(str(textures.SEED_NORMAL))
    mapped = materials.model_material("mapped", "osl", ModelOptions(), lighting, normal_map=image)
    plain = materials.model_material("plain", "osl", ModelOptions(), lighting)
    derivatives = model_node._input(model_node.find(mapped), "normal_derivatives")
    assert derivatives.default_value == 0
    assert model_node._input(model_node.find(plain), "normal_derivatives").default_value == 1

    def rendered(mat, name):
        sphere.data.materials.clear()
        sphere.data.materials.append(mat)
        return render_still(scene, tmp_path / f"{name}.exr")

    without = rendered(mapped, "without")
    derivatives.default_value = 1
    kept = rendered(mapped, "kept")
    flat = rendered(plain, "plain")
    tolerance = 0.0 if bpy.app.version >= (5, 0, 0) else 2e-6
    assert without.max() > 0.05 and abs(without - kept).max() <= tolerance
    assert abs(without - flat).max() > 0.05
