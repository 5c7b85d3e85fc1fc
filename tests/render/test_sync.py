"""Light sync as a user meets it (addon/blender/light_sync.py): the depsgraph handler and the
Sync Lighting operator point every Cook-Torrance material at the world's current HDRI (or, for
a world without an image, a uniform image of its colour) with what its indirect-light mode
needs, and the key light follows the rule the panel states: the chosen Key Sun, else the
scene's first Sun by name, else none."""

import bpy
import numpy as np
import pytest
from mathutils import Vector

from addon.blender import light_sync, model_node, node_group, osl_shader
from addon.core import cache
from addon.core.compare import read_image
from addon.core.hdri import image_width, write_float_exr


def _material(impl):
    cube = bpy.data.objects["Cube"]
    bpy.context.view_layer.objects.active = cube
    assert bpy.ops.ctlab.new_material(implementation=impl) == {'FINISHED'}
    return cube.active_material


def _world_image(scene, path):
    """Give the world an Environment Texture of ``path``, as a user does."""
    nt = scene.world.node_tree
    env = nt.nodes.new("ShaderNodeTexEnvironment")
    env.image = bpy.data.images.load(str(path))
    background = next(n for n in nt.nodes if n.bl_idname == "ShaderNodeBackground")
    nt.links.new(env.outputs["Color"], background.inputs["Color"])


def test_the_handler_follows_the_world_from_its_colour_to_a_new_image(addon, tmp_path):
    scene = bpy.context.scene
    background = next(
        n for n in scene.world.node_tree.nodes if n.bl_idname == "ShaderNodeBackground"
    )
    background.inputs["Color"].default_value = (0.2, 0.3, 0.4, 1.0)
    osl, nodes = _material("osl"), _material("nodes")
    light_sync.on_depsgraph_update(scene)
    osl_node = model_node.find(osl)
    uniform = osl_shader.socket(osl_node, "hdri").default_value
    np.testing.assert_allclose(
        read_image(uniform), np.broadcast_to((0.2, 0.3, 0.4), (8, 16, 3)), rtol=1e-6
    )
    # a new world image: the OSL material gets the file, its width and its tables; the node
    # group its bake
    sky = tmp_path / "sky.exr"
    write_float_exr(sky, np.random.default_rng(5).random((32, 64, 3)).astype(np.float32) + 0.1)
    _world_image(scene, sky)
    assert light_sync.world_hdri_path(scene) == str(sky)
    light_sync.on_depsgraph_update(scene)
    assert osl_shader.socket(osl_node, "hdri").default_value == str(sky)
    assert osl_node.inputs["HDRI Width"].default_value == image_width(sky) == 64
    tables = [
        osl_shader.socket(osl_node, key).default_value
        for key in ("env_marginal", "env_conditional", "env_pdf_table")
    ]
    assert all(t.endswith(".exr") for t in tables)
    from pathlib import Path

    assert cache.intact(Path(tables[0]).parent)
    group = model_node.find(nodes).node_tree
    images = {
        n.image.filepath
        for n in group.nodes
        if n.get(node_group.BAKE_FILE) and getattr(n, "image", None)
    }
    bake = {str(Path(p).parent) for p in images}
    assert len(bake) == 1 and cache.intact(Path(bake.pop()))
    np.testing.assert_allclose(
        read_image(Path(next(iter(images))).parent / "specular_0.exr"), read_image(sky), rtol=1e-6
    )
    # a state already synced is not synced again (the handler runs on every depsgraph update)
    osl_shader.socket(osl_node, "hdri").default_value = "untouched"
    light_sync.on_depsgraph_update(scene)
    assert osl_shader.socket(osl_node, "hdri").default_value == "untouched"


def test_the_key_sun_is_the_chosen_one_else_the_first_by_name_else_none(addon):
    scene = bpy.context.scene
    mat = _material("nodes")
    node = model_node.find(mat)
    suns = {}
    for name, rotation in (("B Sun", (0.5, 0.0, 0.0)), ("A Sun", (0.0, -0.7, 0.3))):
        data = bpy.data.lights.new(name, 'SUN')
        data.energy = 2.0 if name == "A Sun" else 7.0
        suns[name] = bpy.data.objects.new(name, data)
        suns[name].rotation_euler = rotation
        scene.collection.objects.link(suns[name])

    def follows(sun):
        light_sync.sync_material(mat, scene, environment=False)
        scene.frame_set(scene.frame_current)  # evaluates the drivers
        want = sun.matrix_world.to_quaternion() @ Vector((0, 0, 1))
        got = node.inputs["Sun Direction"].default_value
        return (
            max(abs(a - b) for a, b in zip(got, want)) < 1e-5
            and abs(node.inputs["Sun Irradiance"].default_value[0] - sun.data.energy) < 1e-6
        )

    assert light_sync.key_sun(scene) == suns["A Sun"] and follows(suns["A Sun"])
    scene.ctlab_sun = suns["B Sun"]
    assert light_sync.key_sun(scene) == suns["B Sun"] and follows(suns["B Sun"])
    for sun in suns.values():
        bpy.data.objects.remove(sun)
    assert light_sync.key_sun(scene) is None
    light_sync.sync_material(mat, scene, environment=False)
    assert tuple(node.inputs["Sun Irradiance"].default_value)[:3] == (0.0, 0.0, 0.0)


def test_sync_lighting_reports_a_bad_world_image_in_one_line(addon, tmp_path):
    scene = bpy.context.scene
    _material("osl")
    assert bpy.ops.ctlab.sync_lighting() == {'FINISHED'}
    broken = tmp_path / "broken.exr"
    good = tmp_path / "good.exr"
    write_float_exr(good, np.ones((32, 64, 3), np.float32))
    broken.write_bytes(good.read_bytes()[:200])
    _world_image(scene, broken)
    with pytest.raises(RuntimeError, match="HDRI unreadable: .*broken.exr"):
        bpy.ops.ctlab.sync_lighting()
