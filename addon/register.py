"""Blender registration: the sphere-matrix operator and its sidebar panel."""

from __future__ import annotations

import bpy
from bpy.props import EnumProperty, FloatProperty, FloatVectorProperty, IntProperty, StringProperty

from .errors import UserError
from . import osl_shader
from .params import MATRIX_ALBEDO, VIEWS, ModelOptions
from .scene_builder import MAX_GRID, MatrixSettings, build_matrix

_DEFAULTS = MatrixSettings()


class CTLAB_OT_build_sphere_matrix(bpy.types.Operator):
    """Build a metallic x smoothness matrix of spheres lit by an HDRI and a Sun.
    Rebuilding replaces only the objects this operator made"""
    bl_idname = "ctlab.build_sphere_matrix"
    bl_label = "Build Sphere Matrix"
    bl_options = {'REGISTER', 'UNDO'}

    rows: IntProperty(name="Rows (smoothness)", default=_DEFAULTS.rows, min=1, max=MAX_GRID)
    cols: IntProperty(name="Columns (metallic)", default=_DEFAULTS.cols, min=1, max=MAX_GRID)
    spacing: FloatProperty(name="Spacing", default=_DEFAULTS.spacing, min=0.85, max=10,
                           unit='LENGTH', description="Distance between sphere centres")
    albedo: FloatVectorProperty(name="Albedo", subtype='COLOR', size=3, min=0, max=1,
                                default=MATRIX_ALBEDO)
    hdri: StringProperty(name="HDRI", subtype='FILE_PATH', default="",
                         description="Equirectangular HDRI; empty: Blender's bundled forest.exr")
    hdri_strength: FloatProperty(name="HDRI Strength", default=1.0, min=0, soft_max=10)
    hdri_rotation: FloatProperty(name="HDRI Rotation", default=0.0, subtype='ANGLE',
                                 description="Rotation of the world about Z")
    sun_direction: FloatVectorProperty(name="Sun Direction", subtype='DIRECTION', size=3,
                                       default=_DEFAULTS.sun_to_light,
                                       description="Direction toward the Sun")
    sun_strength: FloatProperty(name="Sun Strength", default=_DEFAULTS.sun_strength, min=0,
                                soft_max=20, description="Sun irradiance (W/m²)")
    shader: EnumProperty(name="Shader", default="osl", items=(
        ("osl", "Cook-Torrance (OSL)", "The Cook-Torrance OSL shader (Cycles, CPU)"),
        ("principled", "Principled BSDF", "Blender's Principled BSDF, the reference")))
    view: EnumProperty(name="View", default="full",
                       items=[(v, v.replace("_", " ").title() if len(v) > 2 else v, "")
                              for v in VIEWS])
    resolution: IntProperty(name="Resolution", default=512, min=16, max=4096, subtype='PIXEL')

    def execute(self, context):
        import math
        settings = MatrixSettings(
            rows=self.rows, cols=self.cols, spacing=self.spacing, albedo=tuple(self.albedo),
            hdri=bpy.path.abspath(self.hdri) if self.hdri else "",
            hdri_strength=self.hdri_strength, hdri_rotation=math.degrees(self.hdri_rotation),
            sun_to_light=tuple(self.sun_direction), sun_strength=self.sun_strength,
            shader=self.shader, width=self.resolution, height=self.resolution,
            model=ModelOptions(view=self.view))
        try:
            build_matrix(context.scene, settings)
        except UserError as exc:
            self.report({'ERROR'}, str(exc))
            return {'CANCELLED'}
        scene = context.scene
        scene.render.engine = 'CYCLES'
        scene.cycles.shading_system = (self.shader == "osl")
        self.report({'INFO'}, f"Built a {self.rows}x{self.cols} sphere matrix")
        return {'FINISHED'}

    def invoke(self, context, event):
        return context.window_manager.invoke_props_dialog(self)


class CTLAB_PT_sidebar(bpy.types.Panel):
    bl_label = "Cook-Torrance Lab"
    bl_space_type = 'VIEW_3D'
    bl_region_type = 'UI'
    bl_category = "Cook-Torrance"

    def draw(self, context):
        layout = self.layout
        layout.operator(CTLAB_OT_build_sphere_matrix.bl_idname, icon='MATSPHERE')


CLASSES = (CTLAB_OT_build_sphere_matrix, CTLAB_PT_sidebar)


def register():
    osl_shader.ensure_oslquery()
    for cls in CLASSES:
        bpy.utils.register_class(cls)


def unregister():
    for cls in reversed(CLASSES):
        bpy.utils.unregister_class(cls)
