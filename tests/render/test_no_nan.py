"""No render contains NaN or Inf, at any parameter, normal or light, in any view, and no pixel
is brighter than the physics allows. Randomised: every sphere gets random inputs (out of
range too, and exactly 0 and 1), every pixel a random shading normal (tilted past 80 degrees
and facing away from the viewer included), every view a random Sun (below the horizon
included), under an HDRI whose only light is one texel of radiance 10^6."""

import numpy as np
import pytest

import bpy
from mathutils import Vector

from addon.blender import materials, model_node, renderer, scene_builder
from addon.core.compare import read_image
from addon.core.hdri import write_float_exr
from addon.core.model import ENERGY_MODES, G_MODELS, MIN_ALPHA, VIEWS, ModelOptions
from addon.core.settings import MatrixSettings

PEAK = 1.0e6
BOUNDED = {  # view -> largest value the formulas allow
    "F": 1.0,
    "G": 1.0,
    "NdotL": 1.0,
    "NdotV": 1.0,
    "NdotH": 1.0,
    "VdotH": 1.0,
    "albedo": 1.0,
    "spec_color": 1.0,
    "normal": 1.0,
    "D": 1.0 / (np.pi * MIN_ALPHA**2),
    # diffuse BRDF: diffColor (<= 0.96) x Disney's retro-reflection (<= 2.5 x 2.5) / pi
    "diffuse_brdf": 0.96 * 2.5 * 2.5 / np.pi,
    # indirect light: the brightest incident radiance x the largest directional albedo
    # (specular <= 1 (tests/slow/test_energy.py), Disney diffuse <= 0.96 x 1.5)
    "indirect": 2.5 * PEAK,
    "indirect_specular": 1.0 * PEAK,
    "indirect_diffuse": 1.5 * PEAK,
}


@pytest.fixture(scope="module")
def spike_hdri(tmp_path_factory):
    """Black but for one texel of radiance 10^6 (a 10^6-bright sun)."""
    img = np.zeros((32, 64, 3), dtype=np.float32)
    img[9, 40] = PEAK
    path = tmp_path_factory.mktemp("spike") / "spike.exr"
    write_float_exr(path, img)
    return path


def _random_normals(tree, node):
    """Per-pixel random unit normals from a noise texture, 2c - 1, normalised: all directions,
    back-facing and grazing ones included."""
    noise = tree.nodes.new("ShaderNodeTexWhiteNoise")
    noise.noise_dimensions = '3D'
    coords = tree.nodes.new("ShaderNodeTexCoord")
    scale = tree.nodes.new("ShaderNodeVectorMath")
    scale.operation = 'SCALE'
    scale.inputs["Scale"].default_value = 40.0
    tree.links.new(coords.outputs["Object"], scale.inputs[0])
    tree.links.new(scale.outputs[0], noise.inputs["Vector"])
    centre = tree.nodes.new("ShaderNodeVectorMath")
    centre.operation = 'MULTIPLY_ADD'
    tree.links.new(noise.outputs["Color"], centre.inputs[0])
    centre.inputs[1].default_value = (2.0, 2.0, 2.0)
    centre.inputs[2].default_value = (-1.0, -1.0, -1.0)
    unit = tree.nodes.new("ShaderNodeVectorMath")
    unit.operation = 'NORMALIZE'
    tree.links.new(centre.outputs[0], unit.inputs[0])
    tree.links.new(unit.outputs[0], model_node.surface_input(node, "normal"))


@pytest.mark.parametrize("shader", ["osl", "nodes"])
def test_random_inputs_normals_and_suns_give_finite_bounded_views(tmp_path, spike_hdri, shader):
    rng = np.random.default_rng(7 if shader == "osl" else 8)
    s = MatrixSettings(
        rows=4,
        cols=4,
        width=32,
        height=32,
        hdri=str(spike_hdri),
        shader=shader,
        sun_strength=3.0,
        model=ModelOptions(ibl="reference" if shader == "osl" else "split_sum", env_samples=1),
    )
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    description = scene_builder.build_matrix(scene, s, scene_builder.environment_files(s))
    mat = next(m for m in bpy.data.materials if m.get(scene_builder.TAG))
    node = model_node.find(mat)
    spheres = [o for o in scene.objects if o.type == 'MESH']
    for obj in spheres:
        # exact ends, and out-of-range values the shader must clamp
        obj[materials.PROP_ALBEDO] = list(rng.choice([0.0, 1.0, -0.5, 1.7, rng.random()], 3))
        obj[materials.PROP_METALLIC] = float(rng.choice([0.0, 1.0, -0.2, 1.3, rng.random()]))
        obj[materials.PROP_SMOOTHNESS] = float(rng.choice([0.0, 1.0, -0.1, 1.2, rng.random()]))
    spheres[0][materials.PROP_ALBEDO] = [0.0, 0.0, 0.0]  # a black metal mirror
    spheres[0][materials.PROP_METALLIC], spheres[0][materials.PROP_SMOOTHNESS] = 1.0, 1.0
    _random_normals(mat.node_tree, node)
    sun = next(o for o in scene.objects if o.type == 'LIGHT')
    for k, view in enumerate(VIEWS):
        model_node.set_option(node, "view", view)
        # every G and energy option somewhere (a compensated lobe's factor reaches 3.3)
        model_node.set_option(node, "g_model", G_MODELS[k % len(G_MODELS)])
        model_node.set_option(node, "energy", ENERGY_MODES[(k // 3) % len(ENERGY_MODES)])
        if shader == "osl":
            node.inputs["Seed"].default_value = k
        d = rng.normal(size=3)
        if k % 3 == 0:
            d[2] = -abs(d[2])  # below the horizon
        sun.rotation_mode = 'QUATERNION'
        sun.rotation_quaternion = Vector(d).to_track_quat('Z', 'Y')
        renderer.configure(scene, shader, view, 2, seed=k, pixel_centres=True)
        renderer.render(scene, tmp_path / view, description, log_path=tmp_path / "log.txt")
        img = read_image(tmp_path / view / "render.exr")
        assert np.isfinite(img).all(), f"{shader} view {view}: NaN/Inf"
        if view != "normal":
            assert img.min() >= 0.0, f"{shader} view {view}: negative {img.min()}"
        if view in BOUNDED:
            assert np.abs(img).max() <= BOUNDED[view] * (1 + 1e-4), (
                f"{shader} view {view}: {np.abs(img).max()} > {BOUNDED[view]}"
            )


@pytest.mark.parametrize("shader", ["osl", "nodes"])
def test_lights_at_their_limits_give_finite_views(tmp_path, shader):
    """Lights a hostile scene might hold: a Point almost touching a sphere, a radius far larger
    than the scene, a Spot of 1 degree with no blend, a Sun of angle pi, a tiny Area light and
    an Area light seen from behind, all at once, every view: finite and not negative."""
    from addon.core.lights import parse_light

    lights = tuple(
        parse_light(item, "limits")
        for item in (
            dict(type="POINT", energy=1e6, location=[-0.5, -0.4201, 0.5]),  # 0.1 mm off a sphere
            dict(type="POINT", energy=100.0, location=[1.0, -1.0, 1.0], shadow_soft_size=1e3),
            dict(
                type="SPOT",
                energy=1e5,
                location=[0.5, -3.0, -0.5],
                rotation_euler=[1.5708, 0, 0],
                spot_size=0.0175,
                spot_blend=0.0,
                shadow_soft_size=0.5,
            ),
            dict(type="SUN", energy=10.0, rotation_euler=[0.3, 0.2, 0.1], angle=3.14159),
            dict(type="AREA", energy=1e3, location=[0.5, -0.5, 0.5], size=1e-6),
            dict(
                type="AREA",
                energy=1e3,
                location=[0.0, -2.0, 0.0],
                rotation_euler=[-1.5708, 0, 0],
                shape="ELLIPSE",
                size=2.0,
                size_y=1e-3,
            ),
        )
    )
    s = MatrixSettings(
        rows=2,
        cols=2,
        width=32,
        height=32,
        shader=shader,
        lights=lights,
        model=ModelOptions(
            ibl="reference" if shader == "osl" else "split_sum", env_samples=1, energy="compensated"
        ),
    )
    from addon.jobs import pipeline

    dirs = {view: tmp_path / view for view in VIEWS}
    pipeline.render_views(s, dirs, 2, pixel_centres=True)
    for view, folder in dirs.items():
        img = read_image(folder / "render.exr")
        assert np.isfinite(img).all(), f"{shader} view {view}: NaN/Inf"
        if view != "normal":
            assert img.min() >= 0.0, f"{shader} view {view}: negative {img.min()}"
