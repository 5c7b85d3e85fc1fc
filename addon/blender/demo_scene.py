"""A small real scene for the scene light transport (docs/model.md "Light transport"): the
material on a sphere beside a red cube on a grey floor, an area light, a small emissive panel,
under an HDRI or a Sky Texture world, seen by a perspective camera. The tests, the benchmark
and the docs' images all use this one scene; ``sphere_mask`` finds the sphere's pixels."""

from __future__ import annotations

import math

import bpy
import numpy as np

from .paths import bundled_hdri

SPHERE_RADIUS = 0.6
METAL = {"albedo": (0.9, 0.9, 0.9), "metallic": 1.0, "smoothness": 0.9}
ORANGE = {"albedo": (0.9, 0.35, 0.08), "metallic": 0.0, "smoothness": 0.3}


def principled(name: str, colour, roughness=0.5, metallic=0.0, distribution="GGX"):
    """A plain Principled BSDF material."""
    mat = bpy.data.materials.new(name)
    if mat.node_tree is None:
        mat.use_nodes = True
    bsdf = next(n for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled")
    bsdf.distribution = distribution
    bsdf.inputs["Base Color"].default_value = tuple(colour)[:3] + (1.0,)
    bsdf.inputs["Roughness"].default_value = roughness
    bsdf.inputs["Metallic"].default_value = metallic
    return mat


def principled_for(values: dict, name="Reference", distribution="GGX"):
    """Principled BSDF for the model's values (Roughness = 1 - smoothness)."""
    return principled(
        name, values["albedo"], 1.0 - values["smoothness"], values["metallic"], distribution
    )


def _emitter(name: str, strength: float):
    mat = bpy.data.materials.new(name)
    if mat.node_tree is None:
        mat.use_nodes = True
    nt = mat.node_tree
    nt.nodes.clear()
    em = nt.nodes.new("ShaderNodeEmission")
    em.inputs["Strength"].default_value = strength
    em.inputs["Color"].default_value = (1.0, 0.9, 0.7, 1.0)
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    nt.links.new(em.outputs[0], out.inputs["Surface"])
    return mat


def _mesh_object(name: str, mesh: bpy.types.Mesh, mat, location, rotation=(0, 0, 0)):
    obj = bpy.data.objects.new(name, mesh)
    obj.location = location
    obj.rotation_euler = rotation
    mesh.materials.append(mat)
    bpy.context.scene.collection.objects.link(obj)
    return obj


def _mesh(name: str, build) -> bpy.types.Mesh:
    import bmesh

    bm = bmesh.new()
    build(bm)
    mesh = bpy.data.meshes.new(name)
    bm.to_mesh(mesh)
    bm.free()
    return mesh


def build(world: str = "hdri", width: int = 96, height: int = 72):
    """The scene in a new empty file: ``world`` "hdri" (Blender's forest.exr) or "sky" (a
    Sky Texture). Returns (scene, sphere, second sphere); the spheres have no material yet."""
    import bmesh

    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    w = bpy.data.worlds.new("World")
    if w.node_tree is None:
        w.use_nodes = True
    nt = w.node_tree
    bg = next(n for n in nt.nodes if n.bl_idname == "ShaderNodeBackground")
    if world == "hdri":
        env = nt.nodes.new("ShaderNodeTexEnvironment")
        env.image = bpy.data.images.load(str(bundled_hdri("forest")), check_existing=True)
        nt.links.new(env.outputs["Color"], bg.inputs["Color"])
    else:
        sky = nt.nodes.new("ShaderNodeTexSky")
        nt.links.new(sky.outputs["Color"], bg.inputs["Color"])
        bg.inputs["Strength"].default_value = 0.3
    scene.world = w
    _mesh_object(
        "Floor",
        _mesh("Floor", lambda bm: bmesh.ops.create_grid(bm, x_segments=1, y_segments=1, size=6.0)),
        principled("Grey", (0.5, 0.5, 0.5)),
        (0, 0, 0),
    )
    _mesh_object(
        "Cube",
        _mesh("Cube", lambda bm: bmesh.ops.create_cube(bm, size=1.0)),
        principled("Red", (0.8, 0.05, 0.05)),
        (1.15, 0.2, 0.5),
    )
    _mesh_object(
        "Panel",
        _mesh("Panel", lambda bm: bmesh.ops.create_grid(bm, x_segments=1, y_segments=1, size=0.3)),
        _emitter("Glow", 6.0),
        (-1.3, -0.2, 1.0),
        (0.0, math.radians(70), 0.0),
    )
    light = bpy.data.lights.new("Area", 'AREA')
    light.energy, light.size = 150.0, 1.0
    obj = bpy.data.objects.new("Area", light)
    obj.location = (0.5, -1.5, 3.0)
    scene.collection.objects.link(obj)

    def sphere(bm):
        bmesh.ops.create_uvsphere(bm, u_segments=96, v_segments=48, radius=SPHERE_RADIUS)

    spheres = []
    for name, x in (("Sphere", 0.0), ("Second Sphere", -1.45)):
        mesh = _mesh(name, sphere)
        mesh.shade_smooth()
        obj = bpy.data.objects.new(name, mesh)
        obj.location = (x, 0.0, SPHERE_RADIUS)
        scene.collection.objects.link(obj)
        spheres.append(obj)
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    cam.location = (-0.3, -3.9, 1.2)
    cam.rotation_euler = (math.radians(82), 0.0, 0.0)
    cam.data.lens = 36
    scene.collection.objects.link(cam)
    scene.camera = cam
    scene.render.resolution_x, scene.render.resolution_y = width, height
    scene.render.resolution_percentage = 100
    return scene, spheres[0], spheres[1]


def set_material(obj, mat) -> None:
    if obj.data.materials:
        obj.data.materials[0] = mat
    else:
        obj.data.materials.append(mat)


def sphere_mask(scene, sphere, shape, fraction=0.85) -> np.ndarray:
    """The pixels inside the sphere's image: a conservative disc around its projected centre
    (angular radius asin(r/d) through the camera's focal length, times ``fraction``)."""
    from bpy_extras.object_utils import world_to_camera_view

    cam = scene.camera
    c = world_to_camera_view(scene, cam, sphere.location)
    d = (sphere.location - cam.location).length
    h, w = shape
    f_px = cam.data.lens / cam.data.sensor_width * max(w, h)
    r_px = f_px * math.tan(math.asin(SPHERE_RADIUS / d)) * fraction
    yy, xx = np.mgrid[0:h, 0:w]
    cx, cy = c.x * w, (1.0 - c.y) * h
    return (xx + 0.5 - cx) ** 2 + (yy + 0.5 - cy) ** 2 <= r_px**2
