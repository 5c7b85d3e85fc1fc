"""The add-on's preferences (Edit > Preferences > Add-ons > Cook-Torrance Lab) and the one
accessor the rest of the add-on reads them through.

Without the add-on enabled (the command line, tests importing the modules) ``get()`` returns
the same defaults, so nothing depends on a preferences datablock being there.
"""

from __future__ import annotations

import bpy
from bpy.props import EnumProperty, IntProperty, StringProperty

from ..blender.paths import PACKAGE, preferences
from ..core.model import MAX_SAMPLES
from .labels import IMPLEMENTATION_LABELS

# the node group first: the default (it runs on every back end)
IMPLEMENTATION_ITEMS = tuple((i, *IMPLEMENTATION_LABELS[i]) for i in ("nodes", "osl"))
DEFAULT_SAMPLES = 64


class CTLAB_AddonPreferences(bpy.types.AddonPreferences):
    bl_idname = PACKAGE

    implementation: EnumProperty(
        name="Default Implementation",
        items=IMPLEMENTATION_ITEMS,
        default="nodes",
        description="What new Cook-Torrance materials and conversions use",
    )
    hdri: StringProperty(
        name="Default HDRI",
        subtype='FILE_PATH',
        default="",
        description="Equirectangular HDRI for new sphere matrices and comparisons when the "
        "world has none; empty: Blender's bundled forest.exr",
    )
    cache_folder: StringProperty(
        name="Cache Folder",
        subtype='DIR_PATH',
        default="",
        description="Where baked environments and importance tables are kept; empty: the "
        "extension's user folder",
    )
    samples: IntProperty(
        name="Default Samples",
        default=DEFAULT_SAMPLES,
        min=1,
        max=MAX_SAMPLES,
        description="Render samples of the comparison job",
    )

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
