"""Export Cook-Torrance as MaterialX: the file's Cook-Torrance materials (or the active one) as
one .mtlx each, with their textures, into a folder the user chooses (jobs/export_job.py, the
same writer as ``ctlab export --format materialx``). Nothing in the file is changed."""

from __future__ import annotations

from pathlib import Path

import bpy
from bpy.props import BoolProperty, EnumProperty, StringProperty

from ...blender import material_export, model_node
from ...core.errors import UserError
from ...core.paths import clean, safe_name
from .common import _active_material

_EXPORT_SCOPE = (
    ("ALL", "All Cook-Torrance Materials", "Every material of the file that uses the model"),
    ("ACTIVE", "Active Material", "The active object's active material"),
)


class CTLAB_OT_export_materialx(bpy.types.Operator):
    """Export the Cook-Torrance materials as MaterialX: a .mtlx per material (the model's
    nodedef and a nodegraph of MaterialX's pbrlib nodes) and its textures, into a folder"""

    bl_idname = "ctlab.export_materialx"
    bl_label = "Export Cook-Torrance as MaterialX"
    bl_options = {'REGISTER'}

    directory: StringProperty(name="Folder", subtype='DIR_PATH', default="")
    scope: EnumProperty(name="Materials", items=_EXPORT_SCOPE, default="ALL")
    overwrite: BoolProperty(
        name="Overwrite",
        description="Replace files of the same names in the folder that Cook-Torrance Lab did "
        "not write (by default they are refused and left alone)",
        default=False,
    )

    def invoke(self, context, event):
        context.window_manager.fileselect_add(self)
        return {'RUNNING_MODAL'}

    def execute(self, context):
        from ...jobs.export_job import write_export

        try:
            if not self.directory:
                raise UserError("choose a folder to export into")
            out = clean(bpy.path.abspath(self.directory), "export folder", output=True)
            chosen = None
            if self.scope == 'ACTIVE':
                mat = _active_material(context)
                if model_node.find(mat) is None:
                    raise UserError("the active material does not use the Cook-Torrance model")
                chosen = [mat]
            materials, files, notes = material_export.read_materials(chosen)
            if not materials:
                raise UserError("this file has no Cook-Torrance material to export")
            stem = safe_name(Path(bpy.data.filepath).stem or "untitled", "export")
            inputs = [Path(bpy.data.filepath)] if bpy.data.filepath else []
            written = write_export(
                materials, files, "materialx", out, stem, inputs=inputs, force=self.overwrite
            )
        except UserError as exc:
            self.report({'ERROR'}, str(exc))
            return {'CANCELLED'}
        for note in notes:
            self.report({'WARNING'}, note)
        self.report(
            {'INFO'},
            f"Exported {len(materials)} material(s) as MaterialX: {len(written)} files in {out}",
        )
        return {'FINISHED'}
