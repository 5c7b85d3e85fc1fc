"""The comparisons with Principled BSDF run in the background: the sphere matrix job and a
user's own scene (ctlab scene), and their cancel."""

from __future__ import annotations

import math
from pathlib import Path

import bpy
from bpy.props import BoolProperty, EnumProperty, IntProperty, StringProperty
from mathutils import Vector

from ...blender import light_sync
from ...blender.drivers import world_nodes
from ...core.errors import UserError
from ...core.model import ARTIST, DEFAULT_TRANSPORT, MAX_SAMPLES
from ...core.paths import clean
from ...core.settings import MAX_GRID
from .. import preferences
from ..properties import DIFFUSE_ITEMS, ENERGY_ITEMS, G_ITEMS, TRANSPORT_ITEMS
from .common import _default_hdri
from .jobs import JOBS, _comparison_running, _start_comparison


def default_comparison_folder() -> str:
    if bpy.data.filepath:
        return "//ctlab_comparison"
    from ...core.cache import cache_dir

    return str(cache_dir().parent / "comparison")


class CTLAB_OT_render_comparison(bpy.types.Operator):
    """Render the sphere matrix with Cook-Torrance and Principled BSDF in a background
    process and compare them cell by cell; the report opens when done"""

    bl_idname = "ctlab.render_comparison"
    bl_label = "Render Comparison"
    bl_options = {'REGISTER'}

    directory: StringProperty(
        name="Output Folder",
        subtype='DIR_PATH',
        default="",
        description="Empty: //ctlab_comparison next to the .blend, or the add-on's user folder",
    )
    rows: IntProperty(name="Rows", default=5, min=1, max=MAX_GRID)
    cols: IntProperty(name="Columns", default=5, min=1, max=MAX_GRID)
    size: IntProperty(name="Size", default=384, min=16, max=4096, subtype='PIXEL')
    samples: IntProperty(
        name="Samples",
        default=0,
        min=0,
        max=MAX_SAMPLES,
        description="0: the preferences' default samples",
    )
    open_report: BoolProperty(name="Open Report", default=True)

    def execute(self, context):
        from ...core.files import check_writable
        from ...jobs import background_job
        from ...jobs.cli.parser import argv as job_argv

        if _comparison_running(self):
            return {'CANCELLED'}
        out = Path(bpy.path.abspath(self.directory or default_comparison_folder()))
        scene = context.scene
        hdri = light_sync.world_hdri_path(scene) or _default_hdri()
        values = dict(
            grid=f"{self.rows}x{self.cols}",
            size=self.size,
            samples=self.samples or preferences.get().samples,
        )
        if hdri:
            values["hdri"] = hdri
        background, mapping = world_nodes(scene.world)
        if background is not None and hdri:
            values["hdri_strength"] = background.inputs['Strength'].default_value
        if mapping is not None and hdri:
            values["hdri_rotation"] = math.degrees(mapping.inputs['Rotation'].default_value[2])
        sun = light_sync.key_sun(scene)
        if sun is not None:
            values["sun_dir"] = tuple(sun.matrix_world.to_quaternion() @ Vector((0.0, 0.0, 1.0)))
            values["sun_strength"] = sun.data.energy
        argv = job_argv("matrix", "--out", out, **values)
        try:
            clean(str(out), "output folder", output=True)  # the one path gate, first
            check_writable(out)
            if hdri:
                from ...core.hdri import load_hdri

                load_hdri(Path(hdri))
        except UserError as exc:
            self.report({'ERROR'}, str(exc))
            return {'CANCELLED'}
        job = background_job.Job(argv, out)
        job.open_report = self.open_report
        _start_comparison(context, job)
        self.report({'INFO'}, f"comparison started in the background -> {out}")
        return {'FINISHED'}

    def invoke(self, context, event):
        return context.window_manager.invoke_props_dialog(self)


# "each material's own", before a switch's values (the scene comparison's overrides)
_KEEP = (("MATERIAL", "Each Material's", "Each model material keeps its own setting"),)


class CTLAB_OT_scene_comparison(bpy.types.Operator):
    """Render this scene through its camera twice in a background process, with its
    Cook-Torrance materials and with each converted to Principled BSDF, and compare them
    material by material (ctlab scene); the report opens when done"""

    bl_idname = "ctlab.scene_comparison"
    bl_label = "Compare Scene with Principled"
    bl_options = {'REGISTER'}

    directory: StringProperty(
        name="Output Folder",
        subtype='DIR_PATH',
        default="",
        description="Empty: //ctlab_scene next to the .blend, or the add-on's user folder",
    )
    size: IntProperty(
        name="Size",
        default=384,
        min=16,
        max=4096,
        subtype='PIXEL',
        description="The longer image side (the camera's aspect is kept)",
    )
    samples: IntProperty(
        name="Samples",
        default=0,
        min=0,
        max=MAX_SAMPLES,
        description="0: the preferences' default samples",
    )
    light_transport: EnumProperty(
        name="Light Transport", items=TRANSPORT_ITEMS, default=DEFAULT_TRANSPORT[ARTIST]
    )
    convert: BoolProperty(
        name="Convert Principled",
        default=False,
        description="The other way: the scene's Principled materials "
        "converted to the model, the originals as the reference",
    )
    shader: EnumProperty(
        name="Implementation", items=_KEEP + preferences.IMPLEMENTATION_ITEMS, default="MATERIAL"
    )
    g_model: EnumProperty(name="G", items=_KEEP + G_ITEMS, default="MATERIAL")
    diffuse_model: EnumProperty(name="Diffuse", items=_KEEP + DIFFUSE_ITEMS, default="MATERIAL")
    energy: EnumProperty(name="Energy", items=_KEEP + ENERGY_ITEMS, default="MATERIAL")
    camera: StringProperty(
        name="Camera", default="", description="A camera object of the scene (empty: the scene's)"
    )
    open_report: BoolProperty(name="Open Report", default=True)

    def command(self, blend: Path, out: Path) -> list:
        """The ``ctlab scene`` command line of these settings."""
        argv = [
            "scene",
            str(blend),
            "--out",
            str(out),
            "--size",
            str(self.size),
            "--samples",
            str(self.samples or preferences.get().samples),
            "--light-transport",
            self.light_transport,
        ]
        if self.convert:
            argv.append("--convert")
        for flag, value in (
            ("--shader", self.shader),
            ("--g", self.g_model),
            ("--diffuse", self.diffuse_model),
            ("--energy", self.energy),
            ("--camera", self.camera),
        ):
            if value and value != "MATERIAL":
                argv.append(f"{flag}={value}")
        return argv

    def execute(self, context):
        import shutil
        import tempfile

        from ...core.files import check_writable
        from ...jobs import background_job

        if _comparison_running(self):
            return {'CANCELLED'}
        camera = bpy.data.objects.get(self.camera) if self.camera else context.scene.camera
        if camera is None or camera.type != 'CAMERA':
            self.report(
                {'ERROR'},
                f"no camera named {self.camera!r} in this file"
                if self.camera
                else "the scene has no camera; add one to compare the scene",
            )
            return {'CANCELLED'}
        folder = self.directory or (
            "//ctlab_scene"
            if bpy.data.filepath
            else str(Path(default_comparison_folder()).parent / "scene")
        )
        out = Path(bpy.path.abspath(folder))
        try:
            clean(str(out), "output folder", output=True)  # the one path gate, first
            check_writable(out)
        except UserError as exc:
            self.report({'ERROR'}, str(exc))
            return {'CANCELLED'}
        # the job reads a copy of the file as it is now (the open file is never written)
        staging = Path(tempfile.mkdtemp(prefix="ctlab-scene-"))
        copy = staging / "scene.blend"
        try:
            # relative paths are remapped to the copy's folder, so they still resolve
            bpy.ops.wm.save_as_mainfile(filepath=str(copy), copy=True, relative_remap=True)
        except RuntimeError as exc:
            shutil.rmtree(staging, ignore_errors=True)
            self.report({'ERROR'}, f"cannot copy the scene for the comparison: {exc}")
            return {'CANCELLED'}
        try:
            job = background_job.Job(self.command(copy, out), out)
        except OSError as exc:
            shutil.rmtree(staging, ignore_errors=True)
            self.report({'ERROR'}, f"cannot start the scene comparison: {exc}")
            return {'CANCELLED'}
        job.open_report = self.open_report
        job.staging = staging  # removed when the job ends
        _start_comparison(context, job)
        self.report({'INFO'}, f"scene comparison started in the background -> {out}")
        return {'FINISHED'}

    def invoke(self, context, event):
        return context.window_manager.invoke_props_dialog(self)


class CTLAB_OT_cancel_comparison(bpy.types.Operator):
    """Stop the background comparison after its current render; finished renders are kept"""

    bl_idname = "ctlab.cancel_comparison"
    bl_label = "Cancel Comparison"
    bl_options = {'REGISTER'}

    @classmethod
    def poll(cls, context):
        job = JOBS.get("comparison")
        return job is not None and job.state == "running"

    def execute(self, context):
        JOBS["comparison"].cancel()
        context.window_manager.ctlab_job_state = "cancelling"
        return {'FINISHED'}
