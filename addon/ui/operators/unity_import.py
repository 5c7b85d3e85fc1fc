"""File > Import > Unity Materials (.mat / folder): a Unity project's built-in Standard
materials as Cook-Torrance materials in the open file (jobs/unity_import_job.py, the reader
and builder of ``ctlab import-unity``). Nothing of the Unity folder is written."""

from __future__ import annotations

import os

import bpy
from bpy.props import StringProperty

from ...core.errors import UserError
from ...core.paths import clean
from .common import _implementation, _progress


class CTLAB_OT_import_unity(bpy.types.Operator):
    """Import the built-in Standard materials of a Unity .mat file or of a Unity project or
    Assets folder (textures found through the .meta guids) as Cook-Torrance materials"""

    bl_idname = "ctlab.import_unity"
    bl_label = "Import Unity Materials"
    bl_options = {'REGISTER', 'UNDO'}

    filepath: StringProperty(name="File", subtype='FILE_PATH', default="")
    directory: StringProperty(name="Folder", subtype='DIR_PATH', default="")
    filter_glob: StringProperty(default="*.mat", options={'HIDDEN'})

    def invoke(self, context, event):
        context.window_manager.fileselect_add(self)
        return {'RUNNING_MODAL'}

    def execute(self, context):
        from ...jobs.unity_import_job import build, read_unity

        try:
            chosen = bpy.path.abspath(self.filepath) if self.filepath else ""
            if not chosen or not os.path.isfile(chosen):
                chosen = bpy.path.abspath(self.directory) if self.directory else chosen
            if not chosen:
                raise UserError("choose a Unity .mat file or a Unity project folder")
            found = read_unity(clean(chosen, "Unity path"))
            if not found.surfaces:
                raise UserError(
                    f"no material of Unity's built-in Standard shader in {chosen} "
                    f"({len(found.skipped)} other material(s))"
                )
            with _progress(context, "Importing Unity materials..."):
                mats, warnings = build(found, _implementation("PREFERENCES"), context.scene)
        except UserError as exc:
            self.report({'ERROR'}, str(exc))
            return {'CANCELLED'}
        for line in found.skipped:
            self.report({'INFO'}, f"skipped {line}")
        for line in warnings:
            self.report({'WARNING'}, line)
        for s in found.surfaces:
            if s.not_carried:
                self.report({'INFO'}, f"{s.name}: not carried: {'; '.join(s.not_carried)}")
        self.report(
            {'INFO'},
            f"Imported {len(mats)} Unity material(s) as Cook-Torrance; skipped "
            f"{len(found.skipped)}",
        )
        return {'FINISHED'}


def draw_import_menu(self, context):
    """File > Import: Unity Materials (.mat / folder)."""
    self.layout.operator(CTLAB_OT_import_unity.bl_idname, text="Unity Materials (.mat / folder)")
