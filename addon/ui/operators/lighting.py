"""Light sync: every model material follows the scene's key Sun, lights and world."""

from __future__ import annotations

import bpy

from ...blender import light_sync
from ...core.errors import UserError


def sync_summary(scene, count: int) -> str:
    """What light sync did, in one line: the key Sun (if any), the lights in slots, the world."""
    from ...blender import scene_lights

    sun = light_sync.key_sun(scene)
    used, unused = scene_lights.scene_lights(scene, exclude=sun)
    lights = [f"the key Sun {sun.name}"] if sun else ["no key Sun"]
    if used:
        lights.append(
            f"{len(used)} light{'s' * (len(used) != 1)} in slots "
            f"({', '.join(o.name for o in used)})"
        )
    if unused:
        lights.append(f"{len(unused)} left over")
    return f"{count} material{'s' * (count != 1)} follow {'; '.join(lights)} and the world"


class CTLAB_OT_sync_lighting(bpy.types.Operator):
    """Drive every Cook-Torrance material's key light from the key Sun and its HDRI from the
    world (done by itself when they change; this redoes it now)"""

    bl_idname = "ctlab.sync_lighting"
    bl_label = "Sync Lighting"
    bl_options = {'REGISTER', 'UNDO'}

    def execute(self, context):
        count = 0
        env = light_sync.Environment(context.scene)
        try:
            for mat, _node in light_sync.user_materials():
                light_sync.sync_material(mat, context.scene, env=env)
                count += 1
        except UserError as exc:
            self.report({'ERROR'}, str(exc))
            return {'CANCELLED'}
        self.report({'INFO'}, sync_summary(context.scene, count))
        return {'FINISHED'}
