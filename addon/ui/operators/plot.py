"""The BRDF plot of the active material, in the background (ctlab plot)."""

from __future__ import annotations

from pathlib import Path

import bpy
from bpy.props import BoolProperty, StringProperty

from ...blender import model_node
from ...core.errors import UserError
from ...core.paths import clean
from .common import _active_material
from .jobs import JOBS, PLOT_IMAGE, _start_tick

# ----------------------------------------------------------------------------------------
# The BRDF plot of a material, in the background


def default_plot_folder() -> str:
    """The add-on's user folder (the extension's, or beside the cache): never the install
    folder."""
    from ...core.cache import cache_dir

    return str(cache_dir().parent / "cook-torrance-lab-brdf-plot")


def plot_command(node, out: Path, compare_g: bool = False) -> tuple:
    """``ctlab plot`` for a model node's values (surface inputs as their sockets hold them,
    clamped to the model's range as the model clamps them) and switches; with the notes on
    inputs a texture or another node drives (plotted at the socket's own value)."""
    from ...core.model import G_MODELS, clamp01

    notes, values = [], {}
    for key in ("albedo", "metallic", "smoothness"):
        sock = model_node.surface_input(node, key)
        if sock.is_linked:
            notes.append(
                f"{key} is linked to {sock.links[0].from_node.name}; plotted at the socket's value"
            )
        value = sock.default_value
        values[key] = [clamp01(x) for x in value[:3]] if key == "albedo" else clamp01(value)
    options = {
        k: model_node.get_option(node, k) for k in ("g_model", "diffuse_model", "units", "energy")
    }
    from ...jobs.cli.parser import argv as job_argv

    if compare_g:
        options["compare"] = ",".join(f"g={g}" for g in G_MODELS if g != options["g_model"])
    # written from the command line's own table (jobs/cli/parser.py argv)
    argv = job_argv("plot", out=out, **values, **options, shader=model_node.implementation(node))
    return argv, notes


class CTLAB_OT_brdf_plot(bpy.types.Operator):
    """Plot the active material's BRDF from the model's own code (in a background process):
    the θh × θd slice, the lobes and the directional albedo, shown as the image
    "Cook-Torrance BRDF Plot" in the Image Editor"""

    bl_idname = "ctlab.brdf_plot"
    bl_label = "BRDF Plot"
    bl_options = {'REGISTER'}

    directory: StringProperty(
        name="Output Folder",
        subtype='DIR_PATH',
        default="",
        description="Empty: the add-on's user folder",
    )
    compare_g: BoolProperty(
        name="Compare G Models",
        default=False,
        description="Overlay the other G models' lobes and slices",
    )

    @classmethod
    def poll(cls, context):
        return model_node.find(_active_material(context)) is not None

    def execute(self, context):
        from ...core.files import check_writable
        from ...jobs import background_job

        running = JOBS.get("plot")
        if running is not None and running.poll() == "running":
            self.report({'ERROR'}, "a BRDF plot is already being made; wait for it")
            return {'CANCELLED'}
        node = model_node.find(_active_material(context))
        out = Path(bpy.path.abspath(self.directory or default_plot_folder()))
        try:
            clean(str(out), "output folder", output=True)  # the one path gate, first
            check_writable(out)
        except UserError as exc:
            self.report({'ERROR'}, str(exc))
            return {'CANCELLED'}
        argv, notes = plot_command(node, out, self.compare_g)
        for note in notes:
            self.report({'WARNING'}, note)
        JOBS["plot"] = background_job.Job(argv, out)
        context.window_manager.ctlab_plot_state = "running"
        context.window_manager.ctlab_plot_message = "starting"
        _start_tick()
        self.report({'INFO'}, f"BRDF plot started -> {out}; it opens as the image '{PLOT_IMAGE}'")
        return {'FINISHED'}
