"""The sphere-matrix scene (SPEC "The sphere matrix").

Columns: metallic 0 -> 1 left to right; rows: smoothness 1 -> 0 top to bottom. Smooth-shaded
spheres sharing one mesh and one material (per-sphere values in object custom properties),
an orthographic camera that frames the grid, the world HDRI (Environment Texture behind a
Mapping node's Z rotation, as a Blender user sets it up) and a Sun key light.

Everything the builder makes is tagged ``ctlab_matrix`` and lives in its own collection;
rebuilding removes only tagged data, never a user's objects.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import bpy
from mathutils import Vector

from . import compat, env_importance, ibl_bake, light_sync, materials
from .errors import UserError
from .hdri import load_hdri
from .params import BAKED_IBL_MODES, DEFAULT_ALBEDO, ModelOptions, matrix_values
from .paths import bundled_hdri

TAG = "ctlab_matrix"
COLLECTION = "Cook-Torrance Matrix"
SHADERS = ("osl", "nodes", "principled")     # the OSL shader, the node group, the reference
MAX_GRID = 16
SIZE_RANGE = (16, 4096)


@dataclass
class MatrixSettings:
    rows: int = 7
    cols: int = 7
    spacing: float = 1.0                # distance between sphere centres (m)
    radius: float = 0.42                # sphere radius (m)
    albedo: tuple = DEFAULT_ALBEDO
    hdri: str = ""                      # default: Blender's bundled forest.exr
    hdri_strength: float = 1.0
    hdri_rotation: float = 0.0          # degrees about Z, as the Mapping node
    sun_to_light: tuple = (-0.45, -0.55, 0.70)
    sun_strength: float = 1.0           # irradiance (W/m^2), Blender's Sun strength
    sun_color: tuple = (1.0, 1.0, 1.0)
    shader: str = "osl"
    principled_distribution: str = "MULTI_GGX"
    width: int = 512
    height: int = 512
    model: ModelOptions = field(default_factory=ModelOptions)
    metallic: float | None = None       # every sphere's metallic (None: 0 -> 1 by column)
    # Spheres shadow each other (the Sun's and, in a path tracer, the world's light); off,
    # each sphere is lit by the unoccluded world, as the model's integrator assumes.
    mutual_shadows: bool = True

    def cells(self):
        """(row, col, metallic, smoothness) of every sphere."""
        for row, col, metal, smooth in matrix_values(self.rows, self.cols):
            yield row, col, (metal if self.metallic is None else self.metallic), smooth

    def hdri_path(self) -> Path:
        return Path(self.hdri) if self.hdri else bundled_hdri("forest")

    def to_light(self) -> Vector:
        return Vector(self.sun_to_light).normalized()

    def irradiance(self) -> tuple:
        return tuple(self.sun_strength * c for c in self.sun_color)

    def validate(self) -> None:
        if not (1 <= self.rows <= MAX_GRID and 1 <= self.cols <= MAX_GRID):
            raise UserError(f"grid {self.rows}x{self.cols} out of range; use 1x1 to "
                            f"{MAX_GRID}x{MAX_GRID}")
        for n in (self.width, self.height):
            if not SIZE_RANGE[0] <= n <= SIZE_RANGE[1]:
                raise UserError(f"image size {n} out of range; use {SIZE_RANGE[0]} to {SIZE_RANGE[1]}")
        if self.shader not in SHADERS:
            raise UserError(f"unknown shader {self.shader!r}; choose one of: {', '.join(SHADERS)}")
        if self.shader == "nodes":
            from .node_group import require_baked_ibl
            require_baked_ibl(self.model.ibl)
        vec = self.sun_to_light
        if len(vec) != 3 or not all(math.isfinite(x) for x in vec) or Vector(vec).length < 1e-6:
            raise UserError(f"sun direction {vec} is not a non-zero 3-vector")
        for name in ("hdri_strength", "sun_strength", "hdri_rotation"):
            value = getattr(self, name)
            if not math.isfinite(value) or (name != "hdri_rotation" and value < 0):
                raise UserError(f"{name.replace('_', ' ')} {value} out of range; use a finite "
                                + ("number" if name == "hdri_rotation" else "value >= 0"))
        if self.metallic is not None and not 0.0 <= self.metallic <= 1.0:
            raise UserError(f"metallic {self.metallic} out of range; use 0 to 1")
        if len(self.albedo) != 3 or not all(0.0 <= a <= 1.0 for a in self.albedo):
            raise UserError(f"albedo {self.albedo} out of range; use three values in [0, 1]")
        self.model.validate()


# ----------------------------------------------------------------------------------------
# Geometry of the grid (the camera framing and the cells' pixel positions come from here)

def cell_center(s: MatrixSettings, row: int, col: int) -> Vector:
    """World position of a sphere: the grid lies in the XZ plane, the camera looks along +Y."""
    return Vector(((col - (s.cols - 1) / 2) * s.spacing, 0.0, ((s.rows - 1) / 2 - row) * s.spacing))


def ortho_scale(s: MatrixSettings) -> float:
    """Blender's orthographic scale spans the larger image dimension (sensor fit AUTO)."""
    aspect = s.width / s.height
    return max(s.cols * s.spacing, s.rows * s.spacing * aspect) if aspect >= 1 else \
        max(s.rows * s.spacing, s.cols * s.spacing / aspect)


def world_to_pixel(s: MatrixSettings, p: Vector):
    """Pixel coordinates (origin top-left, x right, y down) of a world point in the XZ plane."""
    scale = ortho_scale(s)
    px_per_m = max(s.width, s.height) / scale
    return (s.width / 2 + p.x * px_per_m, s.height / 2 - p.z * px_per_m), px_per_m


CAMERA_DISTANCE = 20.0
TO_CAMERA = (0.0, -1.0, 0.0)


# ----------------------------------------------------------------------------------------

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
    coll = bpy.data.collections.get(COLLECTION)
    if coll is not None and coll.get(TAG) and not coll.objects:
        bpy.data.collections.remove(coll)


def _tagged(obj):
    obj[TAG] = True
    return obj


def build_world(s: MatrixSettings, image: bpy.types.Image) -> bpy.types.World:
    name = "Cook-Torrance Lab World"
    world = bpy.data.worlds.get(name) or bpy.data.worlds.new(name)
    world[TAG] = True
    compat.use_nodes(world)
    nt = world.node_tree
    nt.nodes.clear()
    coords = nt.nodes.new("ShaderNodeTexCoord")
    mapping = nt.nodes.new("ShaderNodeMapping")
    mapping.vector_type = 'POINT'
    mapping.inputs["Rotation"].default_value = (0.0, 0.0, math.radians(s.hdri_rotation))
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


def build_matrix(scene: bpy.types.Scene, s: MatrixSettings, progress=None) -> dict:
    """Build (or rebuild) the sphere matrix in ``scene``; returns the scene description
    (see ``describe``). Validates everything (and bakes the IBL files the model needs, cached)
    before touching the scene; ``progress(fraction, message)`` follows a bake."""
    s.validate()
    hdri = s.hdri_path()
    load_hdri(hdri)                               # a clear error for a bad HDRI, before any change
    tables, bake = {}, ""
    if s.shader == "osl" and s.model.ibl == "reference":
        tables = env_importance.tables_for(hdri)
    elif s.shader != "principled" and s.model.ibl in BAKED_IBL_MODES:
        bake = ibl_bake.bake(hdri, progress)

    remove_matrix(scene)
    coll = bpy.data.collections.get(COLLECTION)
    if coll is None:
        coll = bpy.data.collections.new(COLLECTION)
        coll[TAG] = True
    if coll.name not in scene.collection.children:
        scene.collection.children.link(coll)

    scene.world = build_world(s, load_image(hdri))

    sun_data = bpy.data.lights.new("Cook-Torrance Lab Sun", 'SUN')
    sun_data.energy = s.sun_strength
    sun_data.color = s.sun_color
    sun_data.angle = 0.0                          # a delta light, as the model's key light
    sun = _tagged(bpy.data.objects.new("Cook-Torrance Lab Sun", sun_data))
    sun.rotation_mode = 'QUATERNION'
    sun.rotation_quaternion = s.to_light().to_track_quat('Z', 'Y')   # +Z toward the light
    coll.objects.link(sun)

    cam_data = bpy.data.cameras.new("Cook-Torrance Lab Camera")
    cam_data.type = 'ORTHO'
    cam_data.ortho_scale = ortho_scale(s)
    cam_data.clip_start, cam_data.clip_end = 0.1, 2 * CAMERA_DISTANCE
    cam = _tagged(bpy.data.objects.new("Cook-Torrance Lab Camera", cam_data))
    cam.location = CAMERA_DISTANCE * Vector(TO_CAMERA)
    cam.rotation_euler = (math.pi / 2, 0.0, 0.0)   # looks along +Y
    coll.objects.link(cam)
    scene.camera = cam
    scene.render.resolution_x, scene.render.resolution_y = s.width, s.height
    scene.render.resolution_percentage = 100
    scene.render.pixel_aspect_x = scene.render.pixel_aspect_y = 1.0

    lighting = materials.Lighting(tuple(s.to_light()), s.irradiance(), str(hdri),
                                  s.hdri_strength, math.radians(s.hdri_rotation), tables, bake)
    if s.shader == "osl":
        mat = materials.cook_torrance_material("Cook-Torrance Matrix", s.model, lighting,
                                               per_object=True)
    elif s.shader == "nodes":
        mat = materials.node_group_material("Cook-Torrance Matrix (nodes)", s.model, lighting,
                                            per_object=True)
    else:
        mat = materials.principled_material("Principled Matrix", per_object=True,
                                            distribution=s.principled_distribution)
    mat[TAG] = True
    if s.shader != "principled":
        # the key light and the world inputs follow the Sun object and the world's nodes
        node = materials.script_node(mat) if s.shader == "osl" else materials.group_node(mat)
        light_sync.add_drivers(mat.node_tree, node, sun, scene.world)

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
        # model's integrator assumes (shadows from the Sun are kept in both renders).
        obj.visible_diffuse = obj.visible_glossy = obj.visible_transmission = False
        obj.visible_shadow = s.mutual_shadows
        coll.objects.link(obj)
    return describe(s)


def _sphere_mesh(mesh: bpy.types.Mesh, radius: float, segments=96, rings=48) -> None:
    """A smooth-shaded UV sphere fine enough that facets never show at matrix resolutions."""
    import bmesh
    bm = bmesh.new()
    bmesh.ops.create_uvsphere(bm, u_segments=segments, v_segments=rings, radius=radius)
    bm.to_mesh(mesh)
    bm.free()
    mesh.shade_smooth()


def describe(s: MatrixSettings) -> dict:
    """The scene as data for scene.json: image size, directions, and each cell in pixels."""
    cells = []
    for row, col, metal, smooth in s.cells():
        (cx, cy), px_per_m = world_to_pixel(s, cell_center(s, row, col))
        cells.append({"row": row, "col": col, "metallic": metal, "smoothness": smooth,
                      "albedo": list(s.albedo), "center_px": [cx, cy],
                      "radius_px": s.radius * px_per_m})
    return {"width": s.width, "height": s.height, "to_camera": list(TO_CAMERA),
            "sun": {"to_light": list(s.to_light()), "irradiance": list(s.irradiance())},
            "hdri": str(s.hdri_path()), "hdri_strength": s.hdri_strength,
            "hdri_rotation_deg": s.hdri_rotation, "shader": s.shader,
            "principled_distribution": s.principled_distribution,
            "rows": s.rows, "cols": s.cols, "model": s.model.as_dict(), "cells": cells}
