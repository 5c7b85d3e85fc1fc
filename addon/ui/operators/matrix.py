"""The sphere matrix in the user's scene, and the bake of an HDRI's split-sum files."""

from __future__ import annotations

from pathlib import Path

import bpy
from bpy.props import (
    BoolProperty,
    EnumProperty,
    FloatProperty,
    FloatVectorProperty,
    IntProperty,
    StringProperty,
)

from ...blender import light_sync
from ...blender.scene_builder import build_matrix, environment_files
from ...core.errors import UserError
from ...core.model import IBL_MODES, MATRIX_ALBEDO, ModelOptions, indirect_light
from ...core.settings import MAX_GRID, MatrixSettings
from ..properties import VIEW_ITEMS
from .common import _DEFAULTS, _IBL_ITEMS, _SHADER_ITEMS, _default_hdri, _progress

# ----------------------------------------------------------------------------------------
# The sphere matrix and the environment bake


class CTLAB_OT_build_sphere_matrix(bpy.types.Operator):
    """Build a metallic x smoothness matrix of spheres lit by an HDRI and a Sun.
    Rebuilding replaces only the objects this operator made"""

    bl_idname = "ctlab.build_sphere_matrix"
    bl_label = "Build Sphere Matrix"
    bl_options = {'REGISTER', 'UNDO'}

    rows: IntProperty(name="Rows (smoothness)", default=_DEFAULTS.rows, min=1, max=MAX_GRID)
    cols: IntProperty(name="Columns (metallic)", default=_DEFAULTS.cols, min=1, max=MAX_GRID)
    spacing: FloatProperty(
        name="Spacing",
        default=_DEFAULTS.spacing,
        min=0.85,
        max=10,
        unit='LENGTH',
        description="Distance between sphere centres",
    )
    albedo: FloatVectorProperty(
        name="Albedo", subtype='COLOR', size=3, min=0, max=1, default=MATRIX_ALBEDO
    )
    hdri: StringProperty(
        name="HDRI",
        subtype='FILE_PATH',
        default="",
        description="Equirectangular HDRI; empty: the preferences' default "
        "HDRI, else Blender's bundled forest.exr",
    )
    hdri_strength: FloatProperty(name="HDRI Strength", default=1.0, min=0, soft_max=10)
    hdri_rotation: FloatProperty(
        name="HDRI Rotation",
        default=0.0,
        subtype='ANGLE',
        description="Rotation of the world about Z",
    )
    sun_direction: FloatVectorProperty(
        name="Sun Direction",
        subtype='DIRECTION',
        size=3,
        default=_DEFAULTS.sun_to_light,
        description="Direction toward the Sun",
    )
    sun_strength: FloatProperty(
        name="Sun Strength",
        default=_DEFAULTS.sun_strength,
        min=0,
        soft_max=20,
        description="Sun irradiance (W/m²)",
    )
    shader: EnumProperty(name="Shader", default="osl", items=_SHADER_ITEMS)
    view: EnumProperty(name="View", default="full", items=VIEW_ITEMS)
    ibl: EnumProperty(name="Indirect Light", default=IBL_MODES[0], items=_IBL_ITEMS)
    resolution: IntProperty(name="Resolution", default=512, min=16, max=4096, subtype='PIXEL')
    seed_textures: BoolProperty(
        name="Seed Textures",
        default=False,
        description="Put the shipped albedo texture and normal map (a brick wall, CC0) on "
        "every sphere, as the seed's prefab had them, where none is chosen below",
    )
    albedo_texture: StringProperty(
        name="Albedo Texture",
        subtype='FILE_PATH',
        default="",
        description="A colour image on every sphere in place of the albedo",
    )
    normal_map: StringProperty(
        name="Normal Map",
        subtype='FILE_PATH',
        default="",
        description="A tangent-space normal map on every sphere (OpenGL convention, green up)",
    )
    normal_strength: FloatProperty(name="Normal Strength", default=1.0, min=0.0, max=10.0)

    def _textures(self) -> dict:
        """The chosen textures, checked (core/textures.py); warnings reported."""
        from ...core.textures import matrix_textures

        found, warnings = matrix_textures(
            bpy.path.abspath(self.albedo_texture) if self.albedo_texture else "",
            bpy.path.abspath(self.normal_map) if self.normal_map else "",
            self.seed_textures,
            self.normal_strength,
        )
        for message in warnings:
            self.report({'WARNING'}, message)
        return found

    def execute(self, context):
        ibl = indirect_light(self.shader, self.ibl) if self.shader != "principled" else self.ibl
        try:
            settings = MatrixSettings(
                rows=self.rows,
                cols=self.cols,
                spacing=self.spacing,
                albedo=tuple(self.albedo),
                hdri=bpy.path.abspath(self.hdri) if self.hdri else _default_hdri(),
                hdri_strength=self.hdri_strength,
                hdri_rotation=self.hdri_rotation,
                sun_to_light=tuple(self.sun_direction),
                sun_strength=self.sun_strength,
                shader=self.shader,
                width=self.resolution,
                height=self.resolution,
                model=ModelOptions(view=self.view, ibl=ibl),
                **self._textures(),
            )
            with _progress(context) as progress:
                files = environment_files(settings, progress)
            build_matrix(context.scene, settings, files)
        except UserError as exc:
            self.report({'ERROR'}, str(exc))
            return {'CANCELLED'}
        scene = context.scene
        scene.render.engine = 'CYCLES'
        scene.cycles.shading_system = self.shader == "osl"
        self.report({'INFO'}, f"Built a {self.rows}x{self.cols} sphere matrix")
        return {'FINISHED'}

    def invoke(self, context, event):
        return context.window_manager.invoke_props_dialog(self)


class CTLAB_OT_bake_environment(bpy.types.Operator):
    """Bake the split-sum files of an HDRI (pre-filtered specular levels, irradiance and the
    DFG tables) into the cache, once per image content"""

    bl_idname = "ctlab.bake_environment"
    bl_label = "Bake Environment"
    bl_options = {'REGISTER'}

    filepath: StringProperty(
        name="HDRI",
        subtype='FILE_PATH',
        default="",
        description="Equirectangular HDRI; empty: the world's Environment "
        "Texture, else Blender's bundled forest.exr",
    )

    def execute(self, context):
        from ...blender.paths import bundled_hdri
        from ...core import ibl_bake

        path = (
            (
                bpy.path.abspath(self.filepath)
                if self.filepath
                else light_sync.world_hdri_path(context.scene)
            )
            or _default_hdri()
            or str(bundled_hdri("forest"))
        )
        warnings = []
        try:
            with _progress(context) as progress:
                folder = ibl_bake.bake(Path(path), progress, warnings.append)
        except UserError as exc:
            self.report({'ERROR'}, str(exc))
            return {'CANCELLED'}
        for message in warnings:
            self.report({'WARNING'}, message)
        context.scene["ctlab_ibl_bake"] = str(folder)
        self.report({'INFO'}, f"Baked {Path(path).name}: {folder}")
        return {'FINISHED'}
