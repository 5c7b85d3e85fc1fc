"""A converted .blend travels (docs/usage.md "What to send to a render farm"): opened in a fresh
process with no add-on, another HOME and no cache, after its folder has moved, it renders as
on the machine that made it; OSL conversion turns OSL on; an appended material follows the new
file's Sun and world.

The renders are Cycles' own: the reference is the render in the making process, the tolerance
Cycles' run-to-run difference between processes (docs/usage.md, task graphs: up to 2.6e-4 on
values up to 18 on 4.5, at most 0.0035 in a few pixels on 5.2) and nothing of the model's.
Mutations seen to fail: without Image.pack() in node_group._float_image the node-group scene
sphere is off by 0.96 (peak 33: the bake's images missing); without the save handlers
(blender/travel.py) the OSL scene sphere is off by 0.22 (its correction reads no files).
"""

import json
import math
import os
import shutil
import subprocess
import sys
import textwrap
import time

import bpy
import numpy as np

from addon.blender import (
    compat,
    convert,
    light_sync,
    model_node,
    node_group,
    osl_shader,
    travel,
)
from addon.core.hdri import read_pixels, write_float_exr
from addon.jobs import scene_job

W, H = 64, 16  # four spheres in a row
SAMPLES = 16

# (object, Principled (base colour, metallic, roughness) or "texture", implementation,
#  transport, extra switches): every file the model reads, in both implementations
SPHERES = (
    ("nodes_scene", ((0.95, 0.64, 0.54), 1.0, 0.3), "nodes", "scene", {}),
    ("nodes_lab", "texture", "nodes", "lab", {}),
    ("osl_scene", ((0.95, 0.64, 0.54), 1.0, 0.3), "osl", "scene", {}),
    ("osl_lab", "texture", "osl", "lab", {"ibl": "split_sum", "energy": "compensated"}),
)

# Runs without the add-on: Blender opens the file (no scripts run, as a farm node's default)
# and renders it; then turns the Sun and reports the driven Sun Direction of each material.
CHILD = textwrap.dedent(
    """
    import json, sys
    import bpy
    path, out = sys.argv[1], sys.argv[2]
    bpy.ops.wm.open_mainfile(filepath=path, load_ui=False, use_scripts=False)
    scene = bpy.context.scene
    scene.render.filepath = out
    bpy.ops.render.render(write_still=True)
    sun = scene.objects["Sun"]
    sun.rotation_euler = (0.3, -0.5, 0.2)
    bpy.context.view_layer.update()
    driven = {}
    for mat in bpy.data.materials:
        for node in mat.node_tree.nodes if mat.node_tree else ():
            sock = node.inputs.get("Sun Direction")
            if sock is not None and node.label == "Cook-Torrance":
                driven[mat.name] = list(sock.default_value)
    print("DRIVEN " + json.dumps({"driven": driven,
          "axis": list(sun.matrix_world.col[2][:3]),
          "modules": sorted(m for m in sys.modules
                      if "ctlab" in m or m == "addon" or m.startswith("addon."))}))
    """
)


def _sky(path):
    """A user's HDRI: a warm horizon, a blue zenith and a bright patch (64 x 32)."""
    h, w = 32, 64
    t = (np.arange(h) + 0.5)[:, None] / h
    img = np.zeros((h, w, 3), np.float32)
    img[...] = np.stack([1.2 - 0.8 * (1 - t), 0.9 - 0.3 * (1 - t), 0.5 + 0.6 * (1 - t)], -1)
    img[6:10, 20:26] = (30.0, 24.0, 18.0)
    write_float_exr(path, img)


def _checker(path):
    image = bpy.data.images.new("Paint", 16, 16)
    px = np.indices((16, 16)).sum(0) % 2
    rgba = np.where(px[..., None], (0.8, 0.2, 0.1, 1.0), (0.1, 0.5, 0.8, 1.0))
    image.pixels.foreach_set(rgba.astype(np.float32).ravel())
    image.filepath_raw = str(path)
    image.file_format = 'PNG'
    image.save()
    return image


def _scene(folder):
    """A product shot of four converted Principled materials under a user's HDRI and a Sun,
    saved as folder/shot.blend (with its HDRI and texture beside it)."""
    scene = bpy.context.scene
    for obj in list(scene.objects):
        bpy.data.objects.remove(obj)
    _sky(folder / "sky.exr")
    world = bpy.data.worlds.new("Sky")
    compat.use_nodes(world)
    env = world.node_tree.nodes.new("ShaderNodeTexEnvironment")
    env.image = bpy.data.images.load(str(folder / "sky.exr"))
    world.node_tree.links.new(env.outputs["Color"], world.node_tree.nodes["Background"].inputs[0])
    scene.world = world
    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", 'SUN'))
    sun.data.energy = 3.0
    sun.rotation_euler = (math.radians(-40), math.radians(30), 0.0)
    scene.collection.objects.link(sun)
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    cam.data.type = 'ORTHO'
    cam.data.ortho_scale = 8.0
    cam.location, cam.rotation_euler = (0.0, -10.0, 0.0), (math.pi / 2, 0.0, 0.0)
    scene.collection.objects.link(cam)
    scene.camera = cam
    paint = _checker(folder / "paint.png")
    for i, (name, surface, impl, transport, switches) in enumerate(SPHERES):
        bpy.ops.mesh.primitive_uv_sphere_add(radius=0.9, location=(-3 + 2 * i, 0.0, 0.0))
        obj = bpy.context.object
        obj.name = name
        bpy.ops.object.shade_smooth()
        mat = bpy.data.materials.new(name)
        compat.use_nodes(mat)
        bsdf = mat.node_tree.nodes["Principled BSDF"]
        if surface == "texture":
            tex = mat.node_tree.nodes.new("ShaderNodeTexImage")
            tex.image = paint
            mat.node_tree.links.new(tex.outputs["Color"], bsdf.inputs["Base Color"])
            bsdf.inputs["Roughness"].default_value = 0.5
        else:
            colour, metallic, roughness = surface
            bsdf.inputs["Base Color"].default_value = colour + (1.0,)
            bsdf.inputs["Metallic"].default_value = metallic
            bsdf.inputs["Roughness"].default_value = roughness
        obj.data.materials.append(mat)
        convert.principled_to_model(mat, scene, impl, transport)
        node = model_node.find(mat)
        for key, value in switches.items():
            model_node.set_option(node, key, value)
        light_sync.sync_material(mat, scene)
    r = scene.render
    r.engine = 'CYCLES'
    r.resolution_x, r.resolution_y, r.resolution_percentage = W, H, 100
    r.image_settings.file_format = 'OPEN_EXR'
    r.image_settings.color_depth = '32'
    cy = scene.cycles
    cy.device = 'CPU'
    cy.samples, cy.seed = SAMPLES, 3
    cy.use_denoising = cy.use_adaptive_sampling = False
    scene.view_settings.view_transform = 'Standard'
    bpy.ops.wm.save_as_mainfile(filepath=str(folder / "shot.blend"))
    return scene


def osl_shader_input(node, key):
    return osl_shader.socket(node, key).default_value


def _render(scene, path):
    scene.render.filepath = str(path)
    bpy.ops.render.render(write_still=True)
    return read_pixels(path, "render")


def test_converted_file_renders_the_same_without_addon_or_cache(addon, tmp_path, monkeypatch):
    """Made with a private cache, saved, moved to another folder, the cache gone: a fresh
    Blender without the add-on (another HOME, XDG_CACHE_HOME and CTLAB_CACHE) renders every
    sphere (node group and OSL, lab and scene transports) as the making process did, reads
    no add-on code and makes no cache; the Sun's drivers still follow the Sun there."""
    cache = tmp_path / "cache"
    monkeypatch.setenv("CTLAB_CACHE", str(cache))
    made = tmp_path / "made"
    made.mkdir()
    scene = _scene(made)
    assert scene.cycles.shading_system  # the OSL conversion turned it on
    reference = _render(scene, tmp_path / "reference.exr")
    groups_images = node_group.table_images()
    assert groups_images and all(i.packed_file is not None for i in groups_images)
    carried = travel.files_folder(made / "shot.blend")
    assert carried.is_dir() and any(carried.iterdir())
    sizes = {p.name: p.stat().st_size for p in (made / "shot.blend", carried)}

    farm = tmp_path / "farm"
    shutil.move(str(made), str(farm))  # another folder, as on a farm's storage
    shutil.move(str(cache), str(tmp_path / "cache-gone"))
    home = tmp_path / "home"
    env = dict(
        os.environ,
        HOME=str(home),
        XDG_CACHE_HOME=str(home / "xdg"),
        CTLAB_CACHE=str(home / "ctlab-cache"),
        PYTHONPATH="",
    )
    p = subprocess.run(
        [sys.executable, "-c", CHILD, str(farm / "shot.blend"), str(tmp_path / "farm.exr")],
        capture_output=True,
        text=True,
        timeout=300,
        cwd=tmp_path,
        env=env,
    )
    assert p.returncode == 0, p.stderr[-2000:]
    report = json.loads(p.stdout.split("DRIVEN ", 1)[1].splitlines()[0])
    assert report["modules"] == []  # the add-on was never imported
    assert not (home / "ctlab-cache").exists()
    assert not (home / "xdg" / "cook-torrance-lab").exists()
    travelled = read_pixels(tmp_path / "farm.exr", "render")

    assert np.isfinite(travelled).all()
    peak = float(reference.max())
    diff = np.abs(travelled - reference)
    print(f"travelled against made: max |diff| {diff.max():.3g}, peak {peak:.3g}")
    # each sphere's own share: none may fail alone
    for i, (name, *_rest) in enumerate(SPHERES):
        cols = slice(i * W // 4, (i + 1) * W // 4)
        mean = float(reference[:, cols].mean())
        assert mean > 0.02, (name, mean)  # lit, not black
        assert float(diff[:, cols].max()) <= 4e-3 * peak, (name, float(diff[:, cols].max()))
    assert float(diff.mean()) <= 1e-4 * peak, (float(diff.mean()), sizes)

    # drivers are simple expressions: they run with scripts off (a farm node's default)
    axis = np.array(report["axis"])
    assert len(report["driven"]) == len(SPHERES)
    for name, value in report["driven"].items():
        assert np.allclose(value, axis, atol=1e-5), (name, value, axis)

    # ctlab scene on the travelled file, whose cache paths are gone: it works, with a cache
    # elsewhere (the making one, moved: an empty cache only adds its build time)
    monkeypatch.setenv("CTLAB_CACHE", str(tmp_path / "cache-gone"))
    t = time.perf_counter()
    metrics = scene_job.run_scene(
        scene_job.SceneJob(farm / "shot.blend", tmp_path / "compared", size=16, samples=1)
    )
    assert sorted(m["name"] for m in metrics["materials"]) == sorted(s[0] for s in SPHERES)
    print(f"ctlab scene: {time.perf_counter() - t:.1f} s")


def test_osl_conversion_turns_osl_on_and_saving_carries_its_files(addon, tmp_path, capsys):
    """Converting to the OSL shader turns the scene's Open Shading Language on (Cycles
    renders the OSL material black without it); the node group leaves it alone. Saving
    writes the OSL files beside the .blend and gives the session its cache paths back; where
    that folder cannot be made (a file of the user's has its name) the file is still saved,
    one line says so, and the user's file is untouched."""
    scene = bpy.context.scene
    scene.render.engine = 'CYCLES'
    scene.cycles.device = 'CPU'
    scene.cycles.shading_system = False
    obj = bpy.data.objects["Cube"]
    mat = bpy.data.materials.new("Paint")
    compat.use_nodes(mat)
    obj.material_slots[0].material = mat  # the active slot
    bpy.context.view_layer.objects.active = obj
    assert bpy.ops.ctlab.convert_to_cook_torrance(implementation="osl") == {'FINISHED'}
    assert scene.cycles.shading_system
    assert model_node.implementation(model_node.find(mat)) == "osl"
    assert model_node.osl_unavailable_reason(scene) is None
    node = model_node.find(mat)
    before = {k: osl_shader_input(node, k) for k in travel.FILE_INPUTS}
    assert before["tables"] and before["hdri"]
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "ok" / "shot.blend"))
    assert any((tmp_path / "ok" / "shot_ctlab").iterdir())
    assert {k: osl_shader_input(node, k) for k in travel.FILE_INPUTS} == before
    (tmp_path / "shot_ctlab").write_text("the user's")
    capsys.readouterr()
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "shot.blend"))
    said = [line for line in capsys.readouterr().out.splitlines() if "Cook-Torrance" in line]
    assert len(said) == 1 and "could not be put beside" in said[0], said
    assert (tmp_path / "shot.blend").is_file()
    assert (tmp_path / "shot_ctlab").read_text() == "the user's"
    assert {k: osl_shader_input(node, k) for k in travel.FILE_INPUTS} == before
    # the node group leaves it alone
    scene.cycles.shading_system = False
    other = bpy.data.materials.new("Other")
    compat.use_nodes(other)
    obj.material_slots[0].material = other
    assert bpy.ops.ctlab.convert_to_cook_torrance(implementation="nodes") == {'FINISHED'}
    assert not scene.cycles.shading_system


def test_appended_material_follows_the_new_files_sun_and_world(addon, tmp_path):
    """A material appended from another file had drivers on that file's Sun and World (they
    came along, as orphans); after the append it follows this file's Sun, world strength and
    rotation, and the other file's Sun and World are left with no users."""
    scene = bpy.context.scene
    for obj in list(scene.objects):
        bpy.data.objects.remove(obj)
    source_sun = bpy.data.objects.new("Source Sun", bpy.data.lights.new("Source Sun", 'SUN'))
    source_sun.rotation_euler = (math.radians(60), 0.0, math.radians(45))
    source_sun.data.energy = 7.0
    scene.collection.objects.link(source_sun)
    mat = bpy.data.materials.new("Travelling")
    compat.use_nodes(mat)
    convert.principled_to_model(mat, scene, "nodes")
    mat.use_fake_user = True
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "source.blend"))

    bpy.ops.wm.read_factory_settings(use_empty=True)
    light_sync.register_handler()  # read_factory_settings keeps persistent handlers
    scene = bpy.context.scene
    world = bpy.data.worlds.new("Here")
    compat.use_nodes(world)
    world.node_tree.nodes["Background"].inputs["Strength"].default_value = 0.25
    scene.world = world
    sun = bpy.data.objects.new("Here Sun", bpy.data.lights.new("Here Sun", 'SUN'))
    sun.rotation_euler = (math.radians(-20), math.radians(35), 0.0)
    sun.data.energy = 2.0
    scene.collection.objects.link(sun)
    bpy.context.view_layer.update()
    with bpy.data.libraries.load(str(tmp_path / "source.blend"), link=False) as (src, dst):
        dst.materials = ["Travelling"]
    appended = dst.materials[0]
    mesh = bpy.data.meshes.new("Box")
    mesh.materials.append(appended)
    scene.collection.objects.link(bpy.data.objects.new("Box", mesh))  # in the depsgraph
    bpy.context.view_layer.update()  # the depsgraph handler sees a new material
    light_sync.on_depsgraph_update(scene)  # as Blender calls it after an update
    node = model_node.find(appended)
    targets = {
        var.targets[0].id.name
        for fc in appended.node_tree.animation_data.drivers
        for var in fc.driver.variables
    }
    assert "Source Sun" not in targets and "Here Sun" in targets and "Here" in targets
    scene.frame_set(scene.frame_current)  # evaluates the drivers
    axis = np.array(sun.matrix_world.col[2][:3])
    direction = np.array(model_node.lighting_input(node, "sun_to_light").default_value)
    assert np.allclose(direction, axis, atol=1e-5), (direction, axis)
    irradiance = model_node.lighting_input(node, "sun_irradiance").default_value
    assert abs(irradiance[0] - 2.0) < 1e-5
    assert abs(model_node.lighting_input(node, "hdri_strength").default_value - 0.25) < 1e-6
    assert bpy.data.objects["Source Sun"].users == 0
