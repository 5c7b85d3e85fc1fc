"""Export Cook-Torrance as MaterialX or as Unity materials: the file's Cook-Torrance materials
(or the active one) as one .mtlx, or one Unity Standard .mat and its .meta, each, with their
textures, into a folder the user chooses (jobs/export_job.py, the same writer as ``ctlab export
--format materialx|unity``). Nothing in the file is changed."""

from __future__ import annotations

from pathlib import Path

import bpy
from bpy.props import BoolProperty, EnumProperty, StringProperty

from ...blender import material_export, model_node
from ...core.errors import UserError
from ...core.unity import mat as unity_mat
from ...core.paths import clean, safe_name
from .common import _active_material

_EXPORT_SCOPE = (
    ("ALL", "All Cook-Torrance Materials", "Every material of the file that uses the model"),
    ("ACTIVE", "Active Material", "The active object's active material"),
)


class _Export:
    """The export operators' common part: the folder, the scope, Overwrite, and the run;
    a subclass names its format (``FORMAT``, ``FORMAT_NAME``) and what it reports after."""

    FORMAT = ""
    FORMAT_NAME = ""
    AFTER = ()  # lines reported once the files are written
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
                materials, files, self.FORMAT, out, stem, inputs=inputs, force=self.overwrite
            )
        except UserError as exc:
            self.report({'ERROR'}, str(exc))
            return {'CANCELLED'}
        for note in notes:
            self.report({'WARNING'}, note)
        for line in self.AFTER:
            self.report({'INFO'}, line)
        self.report(
            {'INFO'},
            f"Exported {len(materials)} material(s) as {self.FORMAT_NAME}: "
            f"{len(written)} files in {out}",
        )
        return {'FINISHED'}


class CTLAB_OT_export_materialx(_Export, bpy.types.Operator):
    """Export the Cook-Torrance materials as MaterialX: a .mtlx per material (the model's
    nodedef and a nodegraph of MaterialX's pbrlib nodes) and its textures, into a folder"""

    bl_idname = "ctlab.export_materialx"
    bl_label = "Export Cook-Torrance as MaterialX"
    FORMAT = "materialx"
    FORMAT_NAME = "MaterialX"


class CTLAB_OT_export_unity(_Export, bpy.types.Operator):
    """Export the Cook-Torrance materials as Unity materials: a .mat of Unity's built-in
    Standard shader (metallic workflow) and its .meta per material, with the albedo, the normal
    map and the packed metallic-smoothness map, into a folder (an Assets folder of a project)"""

    bl_idname = "ctlab.export_unity"
    bl_label = "Export Cook-Torrance as Unity Materials"
    FORMAT = "unity"
    FORMAT_NAME = "Unity materials"
    AFTER = (unity_mat.COLOUR_SPACE_NOTE,)
