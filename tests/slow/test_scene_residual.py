"""The residual albedo of the OSL shader's scene transport (docs/model.md "Light transport"):
what the correction leaves to the closures, the light from other objects, and the render pass
that shows it. In a real scene (blender/demo_scene.py: a cube beside the spheres, a floor, an
area light, an emissive panel, under an HDRI and under a Sky Texture) the renders with the
Cook-Torrance and Unity G differ from the Smith render by exactly what the lab's own
integration of the world and the lights says, with the other objects' occlusion traced; so
the light from the other objects reaches every G through the same (Smith) closures, and the
model's G would change it by at most residual_albedo x the brightest of those objects.

Every render of one world shares Cycles' seed and samples, so the camera samples and the
path tracer's random numbers are the same in each: two renders then differ by the shader's
emissions alone, and are compared pixel by pixel."""

import bpy
import numpy as np
import pytest

from addon.blender import demo_scene, light_sync, materials, model_node, renderer
from addon.blender import scene_builder
from addon.core import compare
from addon.core.hdri import oiio
from addon.core.model import OSL_RESIDUAL, ModelOptions
from addon.core.settings import MatrixSettings
from addon.blender.comparison_render import save_layers
from addon.core.compare import read_material_index

# The residual's bounds: the same on every Blender series, so run on one
# (docs/testing.md, "Which tests run on both series").
pytestmark = pytest.mark.one_series

SMITH = "smith_ggx_correlated"
OTHER_G = ("cook_torrance", "unity_smith_joint")
SAMPLES = 16  # the comparisons are per sample: few will do
SPHERES = {"metal": (demo_scene.METAL, 1), "orange": (demo_scene.ORANGE, 2)}  # pass index
OTHERS = 3  # the pass index of the other objects' materials


def read_layers(path) -> dict:
    """Every channel of a multilayer EXR (all parts), by its full name, as (h, w) float."""
    OIIO = oiio()
    inp = OIIO.ImageInput.open(str(path))
    assert inp is not None, OIIO.geterror()
    channels, part = {}, 0
    try:
        while inp.seek_subimage(part, 0):
            spec = inp.spec()
            px = np.asarray(
                inp.read_image(part, 0, 0, spec.nchannels, OIIO.FLOAT), dtype=np.float32
            ).reshape(spec.height, spec.width, spec.nchannels)
            for c, name in enumerate(spec.channelnames):
                channels[name] = px[..., c]
            part += 1
    finally:
        inp.close()
    return channels


def layer_rgb(channels: dict, layer: str):
    """The RGB of one pass (e.g. "residual_albedo"), or None when the file has no such pass."""
    names = [next((n for n in channels if n.endswith(f".{layer}.{c}")), None) for c in "RGB"]
    if None in names:
        return None
    return np.stack([channels[n] for n in names], axis=-1)


def render_layers(scene, out, path_traced, samples=SAMPLES, pixel_centres=False) -> dict:
    """Render the full view (exact path tracing, seed 0) and save the Render Result whole as
    a multilayer EXR; returns its channels."""
    renderer.configure(
        scene, "osl", "full", samples, pixel_centres=pixel_centres, path_traced=path_traced
    )
    renderer.render(
        scene, out, {"width": scene.render.resolution_x, "height": scene.render.resolution_y}
    )
    save_layers(scene, bpy.data.images["Render Result"], out / "layers.exr")
    return read_layers(out / "layers.exr")


def show_residual(mat, node):
    """Wire the node's residual_albedo output into the surface as an emission (the same
    shading points as the render pass); returns a function that undoes it."""
    nt = mat.node_tree
    out = next(n for n in nt.nodes if n.bl_idname == "ShaderNodeOutputMaterial")
    emit = nt.nodes.new("ShaderNodeEmission")
    nt.links.new(model_node.residual_output(node), emit.inputs["Color"])
    nt.links.new(emit.outputs[0], out.inputs["Surface"])

    def undo():
        nt.links.new(model_node.shader_output(node), out.inputs["Surface"])
        nt.nodes.remove(emit)

    return undo


# --- The render pass ----------------------------------------------------------------------


@pytest.fixture(scope="module")
def residual_pass(tmp_path_factory):
    """One white metal sphere (F = 1, smoothness 0.5), Cook-Torrance G, scene transport, the
    material with the AOV Output and the view layer's AOV that light sync adds where the
    scene asks for the pass; the surface shows the residual as an emission, so that one render
    at the pixel centres holds both the shader's output value (Combined) and the pass."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    s = MatrixSettings(
        rows=1,
        cols=1,
        width=32,
        height=32,
        albedo=(1.0, 1.0, 1.0),
        metallic=1.0,
        sun_strength=0.0,
        mutual_shadows=False,
        model=ModelOptions(light_transport="scene", g_model="cook_torrance", env_samples=64),
    )
    scene = bpy.context.scene
    desc = scene_builder.build_matrix(scene, s, scene_builder.environment_files(s))
    mat = next(m for m in bpy.data.materials if m.get(scene_builder.TAG))
    node = model_node.find(mat)
    # the pass as a scene asks for it (the matrix's material is not a user's: asked directly)
    light_sync.set_residual_pass(scene, True)
    light_sync.update_residual(mat.node_tree, node, scene)
    assert any(
        link.to_node.bl_idname == "ShaderNodeOutputAOV" and link.to_node.aov_name == OSL_RESIDUAL
        for link in model_node.residual_output(node).links
    ), "no AOV Output for the pass"
    show_residual(mat, node)
    out = tmp_path_factory.mktemp("residual-pass")
    channels = render_layers(scene, out, True, samples=1, pixel_centres=True)
    mask = compare.cell_mask((32, 32), desc["cells"][0], 0.9)
    return channels, mask


def test_the_residual_pass_is_in_the_render_result(residual_pass):
    """The render result has the residual_albedo pass (the view layer's AOV), finite and in
    [0, 2] (a specular albedo difference: each of f_G and f_Smith reflects at most about
    one), where the shader's own output, shown as the surface, is positive."""
    channels, mask = residual_pass
    aov = layer_rgb(channels, OSL_RESIDUAL)
    assert aov is not None, sorted(channels)
    assert np.isfinite(aov).all()
    assert aov.min() >= 0.0 and aov.max() <= 2.0, (aov.min(), aov.max())
    shown = layer_rgb(channels, "Combined")
    assert (shown[mask] > 0).all() and shown[mask].max() <= 2.0


@pytest.mark.xfail(
    strict=True,
    reason=(
        "Cycles' OSL backend writes no AOV Output node (OutputAOVNode::compile(OSLCompiler&) is "
        "empty), and the OSL shader renders only with OSL on: the residual_albedo pass that "
        "model_node.connect_residual and light_sync.add_residual_pass set up is all zeros"
    ),
)
def test_the_residual_pass_holds_the_shaders_residual(residual_pass):
    """The pass, read from the render result, is the shader's residual_albedo output at the
    same shading points (which test_scene_transport's quadrature test holds to the
    quadrature of |f_G - f_Smith| (n.l))."""
    channels, mask = residual_pass
    aov, shown = layer_rgb(channels, OSL_RESIDUAL), layer_rgb(channels, "Combined")
    assert np.allclose(aov[mask], shown[mask], rtol=1e-5, atol=1e-7), (
        float(aov[mask].max()),
        float(shown[mask].mean()),
    )


# --- A real scene -------------------------------------------------------------------------


def sphere_masks(scene, spheres, index) -> dict:
    """Each sphere's pixels: inside its conservative disc (demo_scene.sphere_mask) where it
    is the first surface seen (the Material Index pass; the emissive panel hides part of the
    orange sphere), eroded by two pixels (the pixel filter's reach, and more)."""
    pad = np.pad(index, 2, mode="edge")
    h, w = index.shape
    masks = {}
    for name, obj in spheres.items():
        k = SPHERES[name][1]
        own = np.ones_like(index, dtype=bool)
        for dy in range(5):
            for dx in range(5):
                own &= pad[dy : dy + h, dx : dx + w] == k
        masks[name] = own & demo_scene.sphere_mask(scene, obj, index.shape)
    return masks


@pytest.fixture(scope="module", params=["hdri", "sky"])
def real_scene(request, tmp_path_factory):
    """The demo scene with both spheres in the model (the metal one nearly a mirror, the
    orange one a rough dielectric; Lambert diffuse), hidden from the other objects' rays (so
    neither sees its own correction reflected back, nor the other's) but casting shadows, and
    rendered with the same seed and samples: the scene transport with each G, the lab (with
    the HDRI's occlusion traced, and shadow rays) with each G, and each other G's residual
    albedo. Returns (images by (transport, G), residual by G, sphere masks, L_max_other)."""
    world = request.param
    scene, sphere, other = demo_scene.build(world)
    spheres = {"metal": sphere, "orange": other}
    nodes = {}
    for name, obj in spheres.items():
        values, index = SPHERES[name]
        mat = materials.model_material(
            name, "osl", ModelOptions(light_transport="scene", diffuse_model="lambert"), **values
        )
        mat.pass_index = index
        demo_scene.set_material(obj, mat)
        light_sync.sync_material(mat, scene)
        obj.visible_diffuse = obj.visible_glossy = obj.visible_transmission = False
        nodes[name] = (mat, model_node.find(mat))
    for mat in bpy.data.materials:  # the floor, the cube and the panel
        if model_node.find(mat) is None:
            mat.pass_index = OTHERS
    bpy.context.view_layer.use_pass_material_index = True
    root = tmp_path_factory.mktemp(f"real-{world}")

    def set_all(transport, g_model, one_sample=False):
        for _mat, node in nodes.values():
            model_node.set_options(
                node,
                ModelOptions(
                    light_transport=transport,
                    g_model=g_model,
                    diffuse_model="lambert",
                    env_visibility=True,
                    shadow_rays=True,
                    # the same estimator in both transports (their defaults differ): every
                    # technique of the world and the lights, the same draws
                    env_samples=4,
                    one_sample=one_sample,
                ),
            )

    images, residual = {}, {}
    for transport in ("scene", "lab"):
        for g_model in (SMITH,) + OTHER_G:
            set_all(transport, g_model)
            channels = render_layers(scene, root / f"{transport}-{g_model}", transport == "scene")
            images[transport, g_model] = layer_rgb(channels, "Combined")
            if (transport, g_model) == ("scene", SMITH):
                index = read_material_index(root / f"{transport}-{g_model}" / "layers.exr")
    for g_model in OTHER_G:  # the scene transport's own estimator: one technique per sample
        set_all("scene", g_model, one_sample=True)
        channels = render_layers(scene, root / f"one-sample-{g_model}", True)
        images["one sample", g_model] = layer_rgb(channels, "Combined")
    for g_model in (SMITH,) + OTHER_G:
        set_all("scene", g_model)
        undo = [show_residual(mat, node) for mat, node in nodes.values()]
        channels = render_layers(scene, root / f"residual-{g_model}", False)
        residual[g_model] = layer_rgb(channels, "Combined")
        for u in undo:
            u()
    masks = sphere_masks(scene, spheres, index)
    # The radiance arriving at a sphere from the other objects: at most the brightest of them
    # (the emissive panel, Emission 6 x (1, 0.9, 0.7); the floor and the cube, lit by the
    # area light, the world and the panel, as the camera sees them in the Smith render; the
    # other sphere does not reach it), doubled for the directions the camera does not see.
    others = index == OTHERS  # the world's pixels have index 0
    assert others.sum() > 1000
    brightest = images["scene", SMITH][others]
    panel = 6.0 * np.array([1.0, 0.9, 0.7])
    l_max_other = 2.0 * np.maximum(panel, brightest.max(axis=0))
    return world, images, residual, masks, l_max_other


def test_the_residual_is_a_specular_albedo_difference(real_scene):
    """On both spheres the residual albedo is finite, in [0, 2], zero for Smith's G (the
    exact closures) and positive for the other G."""
    world, _images, residual, masks, _l = real_scene
    for name, mask in masks.items():
        assert mask.sum() > 150, (name, int(mask.sum()))
        assert np.isfinite(residual[SMITH]).all()
        assert (residual[SMITH][mask] == 0).all(), (world, name, float(residual[SMITH][mask].max()))
        for g_model in OTHER_G:
            r = residual[g_model][mask]
            assert np.isfinite(r).all() and r.max() <= 2.0, (world, name, g_model, r.max())
            assert (r > 0).all(), (world, name, g_model, r.min())


# Float rounding of a sum of radiances of order 1-10 (the two renders' path-traced parts are
# the same numbers, added to different emissions).
ROUNDING = 2e-5


@pytest.mark.parametrize("g_model", OTHER_G)
def test_the_difference_from_smith_is_the_models_and_within_the_residual(real_scene, g_model):
    """Per sphere pixel, the scene render with this G differs from the Smith render by the
    lab's difference (the model's own integration of the world and the lights, the other
    objects' occlusion traced) to float rounding; what remains, the difference G - Smith
    in the light from the other objects,
      E = (L_G,scene - L_G,lab) - (L_Smith,scene - L_Smith,lab),
    is within residual_albedo x L_max_other (the model's G would reflect that light
    differently from the closures by at most this). Not vacuous: the renders differ, by more
    than the rounding, where the residual is positive."""
    world, images, residual, masks, l_max_other = real_scene
    d_scene = images["scene", g_model] - images["scene", SMITH]
    d_lab = images["lab", g_model] - images["lab", SMITH]
    e = d_scene - d_lab
    for name, mask in masks.items():
        tol = ROUNDING * (1 + np.abs(images["scene", SMITH][mask]))
        err = np.abs(e[mask])
        assert (err <= tol).all(), (
            world,
            name,
            float(err.max()),
            float(np.abs(d_lab[mask]).mean()),
        )
        bound = residual[g_model][mask] * l_max_other + tol
        assert (err <= bound).all(), (world, name)
        differs = np.abs(d_scene[mask]) > 10 * tol
        assert differs.any(), (world, name, float(np.abs(d_scene[mask]).max()))
        assert (residual[g_model][mask][differs] > 0).all()
        print(
            f"{world} {name} {g_model}: |scene - Smith| mean {np.abs(d_scene[mask]).mean():.2e}"
            f" max {np.abs(d_scene[mask]).max():.2e}; |E| max {err.max():.2e}; residual mean "
            f"{residual[g_model][mask].mean():.2e}; L_max_other {l_max_other.max():.2f}"
        )


@pytest.mark.parametrize("g_model", OTHER_G)
def test_the_residual_bound_rejects_the_lab(real_scene, g_model):
    """The bound has teeth. Take the lab's render with this G for the scene's (the mutation:
    no light from other objects, as if the transport ignored them, or the closures lost
    what they carry): the difference is the other objects' light through the closures, far
    above residual_albedo x L_max_other on most of each sphere. And without the correction
    (the scene render with this G replaced by the Smith render) the difference from the
    lab's is the lab's G - Smith difference, above the rounding on both spheres."""
    world, images, residual, masks, l_max_other = real_scene
    mutated = np.abs(images["scene", g_model] - images["lab", g_model])
    d_lab = np.abs(images["lab", g_model] - images["lab", SMITH])
    for name, mask in masks.items():
        tol = ROUNDING * (1 + np.abs(images["scene", SMITH][mask]))
        bound = residual[g_model][mask] * l_max_other + tol
        outside = (mutated[mask] > bound).any(axis=-1)
        assert outside.mean() > 0.5, (world, name, float(outside.mean()))
        assert (d_lab[mask] > 10 * tol).any(), (world, name)
        print(
            f"{world} {name} {g_model}: lab outside the bound on {outside.mean():.0%} of "
            f"the sphere; |lab G - lab Smith| max {d_lab[mask].max():.2e}"
        )


@pytest.mark.parametrize("g_model", OTHER_G)
def test_one_technique_per_sample_estimates_the_same_correction(real_scene, g_model):
    """The scene transport's default estimator (osl/ct_correction.h: per sample one technique,
    the world's or the area light's, divided by its probability) against the lab's (every
    technique, the test above: exact): the same seed, so the closures' part is the same and
    the renders differ by the two corrections' noise alone. On each sphere the mean of that
    difference is within 4 standard errors of 0 in every channel: the one-sample correction
    is unbiased, with the world's occlusion, the area light's shadows and the Sky Texture's
    bake. The bound has teeth: on at least one sphere of each world and G it is under half
    the correction's own mean in every channel (the orange sphere's correction is 18 to 72
    standard errors; the nearly mirror metal's, with the Cook-Torrance G, only 7 to 12), so a
    draw weighed wrong (its probability forgotten: the correction halved or doubled) fails
    it."""
    world, images, _residual, masks, _l = real_scene
    correction = images["scene", g_model] - images["scene", SMITH]
    one = images["one sample", g_model] - images["scene", SMITH]
    resolved = {}
    for name, mask in masks.items():
        d = (one - correction)[mask]
        stderr = d.std(axis=0) / np.sqrt(len(d))
        mean_c = np.abs(correction[mask].mean(axis=0))
        print(
            f"{world} {name} {g_model}: one-sample - lab mean {d.mean(axis=0)}, stderr "
            f"{stderr}, correction's mean {correction[mask].mean(axis=0)}"
        )
        assert (np.abs(d.mean(axis=0)) <= 4 * stderr + ROUNDING).all(), (world, name)
        resolved[name] = bool((4 * stderr < mean_c / 2).all())
    assert any(resolved.values()), resolved
