"""The add-on's preferences (Edit > Preferences > Add-ons > Cook-Torrance Lab) and the one
accessor the rest of the add-on reads them through.

Without the add-on enabled (the command line, tests importing the modules) ``get()`` returns
the same defaults, so nothing depends on a preferences datablock being there.
"""

from __future__ import annotations

import bpy
from bpy.props import EnumProperty, IntProperty, StringProperty

from ..blender.paths import PACKAGE, preferences

IMPLEMENTATION_ITEMS = (
    ("nodes", "Node Group", "The shader-node group: Cycles (CPU or GPU, SVM or OSL) and EEVEE"),
    ("osl", "OSL Shader", "The OSL shader: Cycles on the CPU with Open Shading Language on; "
                          "also offers the reference (Monte Carlo) indirect light"),
)
DEFAULT_SAMPLES = 64


class CTLAB_AddonPreferences(bpy.types.AddonPreferences):
    bl_idname = PACKAGE

    implementation: EnumProperty(
        name="Default Implementation", items=IMPLEMENTATION_ITEMS, default="nodes",
        description="What new Cook-Torrance materials and conversions use")
    hdri: StringProperty(
        name="Default HDRI", subtype='FILE_PATH', default="",
        description="Equirectangular HDRI for new sphere matrices and comparisons when the "
                    "world has none; empty: Blender's bundled forest.exr")
    cache_folder: StringProperty(
        name="Cache Folder", subtype='DIR_PATH', default="",
        description="Where baked environments and importance tables are kept; empty: the "
                    "extension's user folder")
    samples: IntProperty(
        name="Default Samples", default=DEFAULT_SAMPLES, min=1, max=65536,
        description="Render samples of the comparison job")

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.prop(self, "implementation")
        layout.prop(self, "hdri")
        layout.prop(self, "cache_folder")
        layout.prop(self, "samples")


class _Defaults:
    implementation = "nodes"
    hdri = ""
    cache_folder = ""
    samples = DEFAULT_SAMPLES


def get():
    """The preferences, or their defaults when the add-on is not enabled under its name."""
    return preferences() or _Defaults
