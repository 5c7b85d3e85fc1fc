"""The scene transport's Correction Depth (docs/model.md "The correction's depth"): the
correction is added at hits of a ray depth below it, and deeper the material is its closures
alone.

The camera sees the model's sphere only in a perfect mirror (a white Principled metal of
roughness 0, at 45 degrees), so every pixel of the sphere is a hit of ray depth 1. There:
- with Correction Depth 1 the sphere is its closures alone, which are the same for the
  Cook-Torrance G as for Smith's G (f_closure has Smith's G): the render equals, to float
  rounding, the render of the Smith-G material (whose closures are the model, uncorrected at every
  depth);
- with Correction Depth 2 the correction is back: the render differs from that one by more
  than the noise of a second seed, and equals the render with the correction at every depth
  (1024) within that noise on the sphere's mean (what is left is light that reached the
  sphere after more bounces).
Both implementations."""

import math

import bpy
import numpy as np
import pytest

from addon.blender import compat, light_sync, materials, model_node, renderer
from addon.blender.paths import resolve_hdri
from addon.core import compare
from addon.core.model import ModelOptions

SIZE, SAMPLES = 48, 16
SURFACE = dict(albedo=(0.95, 0.64, 0.54), metallic=1.0, smoothness=0.35)


def _mirror_scene():
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    world = bpy.data.worlds.new("forest")
    compat.use_nodes(world)
    nt = world.node_tree
    env = nt.nodes.new("ShaderNodeTexEnvironment")
    env.image = bpy.data.images.load(str(resolve_hdri("")))
    nt.links.new(env.outputs["Color"], nt.nodes["Background"].inputs["Color"])
    scene.world = world
    cam = bpy.data.objects.new("camera", bpy.data.cameras.new("camera"))
    cam.data.type = 'ORTHO'
    cam.data.ortho_scale = 1.1
    cam.rotation_euler = (math.pi / 2, 0.0, 0.0)  # looking along +y
    scene.collection.objects.link(cam)
    scene.camera = cam
    bpy.ops.mesh.primitive_plane_add(size=3.0, location=(0.0, 3.0, 0.0))
    mirror = bpy.context.object
    mirror.rotation_euler = (math.pi / 4, 0.0, 0.0)  # normal (0, -1, 1)/sqrt 2: +y to +z
    mat = bpy.data.materials.new("mirror")
    compat.use_nodes(mat)
    bsdf = mat.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Base Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    bsdf.inputs["Metallic"].default_value = 1.0
    bsdf.inputs["Roughness"].default_value = 0.0
    mirror.data.materials.append(mat)
    bpy.ops.mesh.primitive_uv_sphere_add(radius=0.5, location=(0.0, 3.0, 3.0), segments=64)
    bpy.ops.object.shade_smooth()
    scene.render.resolution_x = scene.render.resolution_y = SIZE
    return scene, bpy.context.object


def _render(tmp_path, impl, g_model, depth, seed=0):
    scene, sphere = _mirror_scene()
    options = ModelOptions(
        light_transport="scene",
        g_model=g_model,
        energy="none",
        ibl="split_sum" if impl == "nodes" else "reference",
        env_samples=1,
        seed=seed,
    )
    mat = materials.model_material("sphere", impl=impl, options=options, **SURFACE)
    sphere.data.materials.append(mat)
    light_sync.sync_material(mat, scene)
    node = model_node.find(mat)
    node.inputs["Correction Depth"].default_value = depth
    renderer.configure(scene, impl, "full", SAMPLES, seed, path_traced=True)
    out = tmp_path / f"{impl}-{g_model}-{depth}-{seed}"
    renderer.render(scene, out, {}, None)
    image = compare.read_image(out / "render.exr")[..., :3]
    assert np.isfinite(image).all()
    return image


def _disc():
    """The sphere's pixels in the mirror (radius 0.5 of an image 1.1 wide), a margin in."""
    c = (np.arange(SIZE) + 0.5) / SIZE * 1.1 - 0.55
    x, z = np.meshgrid(c, c)
    return x**2 + z**2 < 0.45**2


@pytest.mark.parametrize("impl", ["osl", "nodes"])
def test_the_correction_reaches_the_depth_it_is_given(tmp_path, impl):
    disc = _disc()
    closures = _render(tmp_path, impl, "cook_torrance", 1)
    smith = _render(tmp_path, impl, "smith_ggx_correlated", 1)
    # the same closures, the same samples: equal to float rounding (bit for bit on 5.2; 4.5's
    # OSL optimiser folds the closures' weights in another order, 2e-5 at most)
    diff = float(np.abs(closures - smith).max())
    assert diff <= 1e-4 * float(smith.max()), (
        f"at depth 1 with Correction Depth 1 the sphere is not its closures alone: max "
        f"difference {diff:.3g} from the Smith-G material's"
    )
    corrected = _render(tmp_path, impl, "cook_torrance", 2)
    everywhere = _render(tmp_path, impl, "cook_torrance", 1024)
    other_seed = _render(tmp_path, impl, "cook_torrance", 2, seed=1)
    mean = {
        k: float(v[disc].mean())
        for k, v in (
            ("closures", closures),
            ("corrected", corrected),
            ("everywhere", everywhere),
            ("other seed", other_seed),
        )
    }
    noise = abs(mean["other seed"] - mean["corrected"])
    print(impl, mean, f"noise {noise:.4f}")
    assert abs(mean["corrected"] - mean["closures"]) > max(5 * noise, 0.01 * mean["closures"])
    assert abs(mean["everywhere"] - mean["corrected"]) <= max(3 * noise, 0.005 * mean["corrected"])
