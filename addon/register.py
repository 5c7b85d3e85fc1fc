"""Blender registration: the sphere-matrix and bake operators and their sidebar panel."""

from __future__ import annotations

import bpy
from bpy.props import EnumProperty, FloatProperty, FloatVectorProperty, IntProperty, StringProperty

from .errors import UserError
from . import osl_shader
from .params import IBL_LABELS, IBL_MODES, MATRIX_ALBEDO, VIEWS, ModelOptions
from .scene_builder import MAX_GRID, MatrixSettings, build_matrix

_DEFAULTS = MatrixSettings()
_IBL_ITEMS = [(m, *IBL_LABELS[m]) for m in IBL_MODES]


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
    ibl: EnumProperty(name="Indirect Light", default=IBL_MODES[0], items=_IBL_ITEMS)
    resolution: IntProperty(name="Resolution", default=512, min=16, max=4096, subtype='PIXEL')

    def execute(self, context):
        import math
        settings = MatrixSettings(
            rows=self.rows, cols=self.cols, spacing=self.spacing, albedo=tuple(self.albedo),
            hdri=bpy.path.abspath(self.hdri) if self.hdri else "",
            hdri_strength=self.hdri_strength, hdri_rotation=math.degrees(self.hdri_rotation),
            sun_to_light=tuple(self.sun_direction), sun_strength=self.sun_strength,
            shader=self.shader, width=self.resolution, height=self.resolution,
            model=ModelOptions(view=self.view, ibl=self.ibl))
        try:
            with _progress(context) as progress:
                build_matrix(context.scene, settings, progress)
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


class _progress:
    """The window manager's progress indicator (a no-op without a window), as a
    ``progress(fraction, message)`` callable."""

    def __init__(self, context):
        self.wm = context.window_manager if context.window else None

    def __enter__(self):
        if self.wm is not None:
            self.wm.progress_begin(0, 100)
        return self

    def __call__(self, fraction, message):
        if self.wm is not None:
            self.wm.progress_update(int(100 * fraction))

    def __exit__(self, *exc):
        if self.wm is not None:
            self.wm.progress_end()


def world_hdri_path(scene) -> str:
    """The image file of the scene world's Environment Texture, or "" when there is none."""
    world = scene.world
    if world is None or world.node_tree is None:
        return ""
    for node in world.node_tree.nodes:
        if node.bl_idname == "ShaderNodeTexEnvironment" and node.image is not None:
            return bpy.path.abspath(node.image.filepath, library=node.image.library)
    return ""


class CTLAB_OT_bake_environment(bpy.types.Operator):
    """Bake the split-sum files of an HDRI (pre-filtered specular levels, irradiance and the
    DFG tables) into the cache, once per image content"""
    bl_idname = "ctlab.bake_environment"
    bl_label = "Bake Environment"
    bl_options = {'REGISTER'}

    filepath: StringProperty(name="HDRI", subtype='FILE_PATH', default="",
                             description="Equirectangular HDRI; empty: the world's Environment "
                                         "Texture, else Blender's bundled forest.exr")

    def execute(self, context):
        from pathlib import Path
        from . import ibl_bake
        from .paths import bundled_hdri
        path = (bpy.path.abspath(self.filepath) if self.filepath
                else world_hdri_path(context.scene)) or str(bundled_hdri("forest"))
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


class CTLAB_PT_sidebar(bpy.types.Panel):
    bl_label = "Cook-Torrance Lab"
    bl_space_type = 'VIEW_3D'
    bl_region_type = 'UI'
    bl_category = "Cook-Torrance"

    def draw(self, context):
        layout = self.layout
        layout.operator(CTLAB_OT_build_sphere_matrix.bl_idname, icon='MATSPHERE')
        layout.operator(CTLAB_OT_bake_environment.bl_idname, icon='WORLD')
        bake = context.scene.get("ctlab_ibl_bake")
        if bake:
            layout.label(text=f"Baked: {bake}", icon='CHECKMARK')


CLASSES = (CTLAB_OT_build_sphere_matrix, CTLAB_OT_bake_environment, CTLAB_PT_sidebar)


def register():
    osl_shader.ensure_oslquery()
    for cls in CLASSES:
        bpy.utils.register_class(cls)


def unregister():
    for cls in reversed(CLASSES):
        bpy.utils.unregister_class(cls)
