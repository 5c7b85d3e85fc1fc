"""Registration of everything the add-on adds to Blender, and its exact removal: classes
(operators, panels, preferences), properties, the Add-menu entry, the lighting handler, the
saving handlers that let a file travel (blender/travel.py) and any background job.
Unregistering leaves nothing behind and re-registering works."""

from __future__ import annotations

import bpy

from . import operators, panels, preferences, properties
from ..blender import light_sync, osl_shader, travel

CLASSES = (preferences.CTLAB_AddonPreferences,) + operators.CLASSES + panels.PANELS


def register():
    try:
        osl_shader.ensure_oslquery()
    except Exception as exc:  # the node group still works without OSL
        print(f"Cook-Torrance Lab: {exc}")
    for cls in CLASSES:
        bpy.utils.register_class(cls)
    properties.register()
    for menu, draw in panels.MENU_ENTRIES:
        getattr(bpy.types, menu).append(draw)
    light_sync.register_handler()
    travel.register_handlers()


def unregister():
    operators.stop_jobs()
    light_sync.unregister_handler()
    travel.unregister_handlers()
    for menu, draw in panels.MENU_ENTRIES:
        getattr(bpy.types, menu).remove(draw)
    properties.unregister()
    for cls in reversed(CLASSES):
        bpy.utils.unregister_class(cls)
