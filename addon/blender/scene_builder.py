"""The sphere-matrix scene (docs/model.md "The sphere matrix"), built from core.settings.

Smooth-shaded spheres sharing one mesh and one material (per-sphere values in object custom
properties), an orthographic camera that frames the grid, the world HDRI (Environment Texture
behind a Mapping node's Z rotation, as a Blender user sets it up) and a Sun key light.

Everything the builder makes is tagged ``ctlab_matrix`` and lives in its own collection;
rebuilding removes only tagged data, never a user's objects.
"""

from __future__ import annotations

import math
from pathlib import Path

import bpy
from mathutils import Vector

from . import compat, materials, model_node, owned, scene_lights
from .paths import resolve_hdri
from ..core import env_importance, ibl_bake
from ..core.hdri import load_hdri
from ..core.model import Lighting, files_needed
from ..core.textures import UV_SCALE
from ..core.settings import (
    CAMERA_DISTANCE,
    TO_CAMERA,
    MatrixSettings,
    cell_center,
    describe,
    ortho_scale,
)

TAG = owned.MATRIX  # the role of the matrix's world and collection (blender/owned.py)
COLLECTION = "Cook-Torrance Matrix"


def remove_matrix(scene: bpy.types.Scene) -> None:
    """Remove what an earlier build made (tagged data only)."""
    tagged = [o for o in bpy.data.objects if o.get(TAG)]
    data = {o.data for o in tagged if o.data is not None}
    for obj in tagged:
        bpy.data.objects.remove(obj)
    for block in data:
        if block.users == 0:
            for collection in (bpy.data.meshes, bpy.data.cameras, bpy.data.lights):
                if block.name in collection and collection[block.name] == block:
                    collection.remove(block)
                    break
    coll = owned.find(bpy.data.collections, COLLECTION, TAG)
    if coll is not None and not coll.objects:
        bpy.data.collections.remove(coll)


def _tagged(obj):
    obj[TAG] = True
    return obj


def build_world(s: MatrixSettings, image: bpy.types.Image) -> bpy.types.World:
    """The matrix's world, ours (blender/owned.py): a user's world of its name is never
    reused or cleared; ours is then "Cook-Torrance Lab World.001"."""
    name = "Cook-Torrance Lab World"
    world = owned.find(bpy.data.worlds, name, TAG) or owned.new(bpy.data.worlds, name, TAG)
    world[TAG] = True
    compat.use_nodes(world)
    nt = world.node_tree
    nt.nodes.clear()
    coords = nt.nodes.new("ShaderNodeTexCoord")
    mapping = nt.nodes.new("ShaderNodeMapping")
    mapping.vector_type = 'POINT'
    mapping.inputs["Rotation"].default_value = (0.0, 0.0, s.hdri_rotation)
    env = nt.nodes.new("ShaderNodeTexEnvironment")
    env.image = image
    env.interpolation = 'Linear'
    env.projection = 'EQUIRECTANGULAR'
    background = nt.nodes.new("ShaderNodeBackground")
    background.inputs["Strength"].default_value = s.hdri_strength
    output = nt.nodes.new("ShaderNodeOutputWorld")
    for i, node in enumerate((coords, mapping, env, background, output)):
        node.location = (-900 + 250 * i, 0)
    nt.links.new(coords.outputs["Generated"], mapping.inputs["Vector"])
    nt.links.new(mapping.outputs["Vector"], env.inputs["Vector"])
    nt.links.new(env.outputs["Color"], background.inputs["Color"])
    nt.links.new(background.outputs["Background"], output.inputs["Surface"])
    return world


def load_image(path: Path) -> bpy.types.Image:
    image = bpy.data.images.load(str(path), check_existing=True)
    image.colorspace_settings.name = "Linear Rec.709"
    return image


def environment_files(s: MatrixSettings, progress=None) -> tuple:
    """What the model of ``s`` reads besides its HDRI (core.model.files_needed), made or found
    in the cache: (the importance tables or {}, the bake folder or ""). A bad HDRI is a
    UserError; ``progress(fraction, message)`` follows a bake."""
    hdri = resolve_hdri(s.hdri)
    load_hdri(hdri)  # a clear error for a bad HDRI, before any change
    tables, bake = {}, ""
    need = files_needed(s.shader, s.model.ibl, s.model.light_transport)
    if "tables" in need:
        tables = env_importance.tables_for(hdri)  # the reference IBL, the scene correction
    if "bake" in need:
        bake = ibl_bake.bake(hdri, progress)
    return tables, bake


def build_matrix(scene: bpy.types.Scene, s: MatrixSettings, files: tuple) -> dict:
    """Build (or rebuild) the sphere matrix in ``scene`` from the settings and their
    ``environment_files`` (made beforehand: the builder bakes nothing); returns the scene
    description (core.settings.describe). Changes nothing in the scene before it has checked
    the settings' HDRI."""
    hdri = resolve_hdri(s.hdri)
    load_hdri(hdri)  # a clear error for a bad HDRI, before any change
    tables, bake = files

    remove_matrix(scene)
    coll = owned.find(bpy.data.collections, COLLECTION, TAG)  # a user's of its name: never
    if coll is None:
        coll = owned.new(bpy.data.collections, COLLECTION, TAG)
        coll[TAG] = True
    if coll.name not in scene.collection.children:
        scene.collection.children.link(coll)

    scene.world = build_world(s, load_image(hdri))

    # The key light: a delta Sun; or, with a lights list, those lights in its place.
    sun, light_objects = None, []
    if s.lights:
        for i, light in enumerate(s.lights):
            obj = _tagged(
                scene_lights.new_light_object(
                    light, light.name or f"Cook-Torrance Lab Light {i + 1}"
                )
            )
            coll.objects.link(obj)
            light_objects.append(obj)
    else:
        sun_data = bpy.data.lights.new("Cook-Torrance Lab Sun", 'SUN')
        sun_data.energy = s.sun_strength
        sun_data.color = s.sun_color
        sun_data.angle = 0.0  # a delta light, as the model's key light
        sun = _tagged(bpy.data.objects.new("Cook-Torrance Lab Sun", sun_data))
        sun.rotation_mode = 'QUATERNION'
        sun.rotation_quaternion = Vector(s.to_light()).to_track_quat('Z', 'Y')  # +Z toward it
        coll.objects.link(sun)

    cam_data = bpy.data.cameras.new("Cook-Torrance Lab Camera")
    cam_data.type = 'ORTHO'
    cam_data.ortho_scale = ortho_scale(s)
    cam_data.clip_start, cam_data.clip_end = 0.1, 2 * CAMERA_DISTANCE
    cam = _tagged(bpy.data.objects.new("Cook-Torrance Lab Camera", cam_data))
    cam.location = CAMERA_DISTANCE * Vector(TO_CAMERA)
    cam.rotation_euler = (math.pi / 2, 0.0, 0.0)  # looks along +Y
    coll.objects.link(cam)
    scene.camera = cam
    scene.render.resolution_x, scene.render.resolution_y = s.width, s.height
    scene.render.resolution_percentage = 100
    scene.render.pixel_aspect_x = scene.render.pixel_aspect_y = 1.0

    lighting = Lighting(
        s.to_light(),
        s.irradiance() if sun else (0.0, 0.0, 0.0),
        str(hdri),
        s.hdri_strength,
        s.hdri_rotation,
        tables,
        str(bake),
    )
    textures = _texture_images(s)
    if s.shader == "principled":
        mat = materials.principled_material(
            "Principled Matrix",
            per_object=True,
            distribution=s.principled_distribution,
            **textures,
        )
    else:
        # shadow rays stop at the other spheres only where Principled's would
        mat = materials.model_material(
            "Cook-Torrance Matrix",
            s.shader,
            s.model_options(),
            lighting,
            per_object=True,
            **textures,
        )
        # the key light, the lights and the world inputs follow the scene's objects
        node = model_node.find(mat)
        model_node.add_drivers(mat.node_tree, node, sun, scene.world)
        scene_lights.sync_slots(mat.node_tree, node, light_objects)
    mat[TAG] = True

    mesh = bpy.data.meshes.new("Cook-Torrance Lab Sphere")
    _sphere_mesh(mesh, s.radius)
    mesh.materials.append(mat)
    for row, col, metal, smooth in s.cells():
        obj = _tagged(bpy.data.objects.new(f"CT Sphere r{row} c{col}", mesh))
        obj.location = cell_center(s, row, col)
        obj[materials.PROP_ALBEDO] = list(s.albedo)
        obj[materials.PROP_METALLIC] = metal
        obj[materials.PROP_SMOOTHNESS] = smooth
        obj["ctlab_row"], obj["ctlab_col"] = row, col
        # Spheres do not see each other: each is lit by the world and the Sun alone, as the
        # model's integrator assumes. They cast shadows (the Sun's, and in Principled's path
        # tracer the world's) unless the settings turn mutual shadows off (the parity job).
        obj.visible_diffuse = obj.visible_glossy = obj.visible_transmission = False
        obj.visible_shadow = s.mutual_shadows
        coll.objects.link(obj)
    return describe(s, hdri)


def _texture_images(s) -> dict:
    """The settings' albedo texture and normal map as images (core/textures.py), for
    materials.model_material and principled_material: the albedo in the colour space Blender
    gives its file (sRGB for 8-bit images, linear for float ones), the normal map as data."""
    found = {"normal_strength": s.normal_strength}
    if s.albedo_texture:
        found["albedo_image"] = bpy.data.images.load(s.albedo_texture, check_existing=True)
    if s.normal_map:
        found["normal_map"] = bpy.data.images.load(s.normal_map, check_existing=True)
    return found


def _sphere_mesh(mesh: bpy.types.Mesh, radius: float, segments=96, rings=48) -> None:
    """A smooth-shaded UV sphere fine enough that facets never show at matrix resolutions,
    with the UV map Blender makes for a UV sphere scaled by core/textures.py UV_SCALE (the
    textures repeat twice around, once pole to pole; the normal map's tangents follow it).
    The scale lives in the mesh, not in a Mapping node: a node costs every shading point of
    every render (Cycles' OSL runs it as a shader call), the mesh's UVs nothing."""
    import bmesh

    bm = bmesh.new()
    uv = bm.loops.layers.uv.new("UVMap")
    bmesh.ops.create_uvsphere(
        bm, u_segments=segments, v_segments=rings, radius=radius, calc_uvs=True
    )
    su, sv = UV_SCALE[0], UV_SCALE[1]
    for face in bm.faces:
        for loop in face.loops:
            u, v = loop[uv].uv
            loop[uv].uv = (u * su, v * sv)
    bm.to_mesh(mesh)
    bm.free()
    mesh.shade_smooth()
