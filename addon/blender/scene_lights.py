"""The scene's lights and the model's light slots (docs/model.md "Lights").

Which lights the model shades: the light objects of the view layer that render (not disabled
for rendering, in no collection disabled for rendering), but the key Sun (which has inputs of
its own). They take the LIGHT_SLOTS slots in core.lights.ranked's order (Suns first, then the
most powerful); the rest are reported, not shaded. A slot's continuous values follow its light
through drivers (drivers.add_light_drivers); its Type, and which light holds which slot, are
set here when the set of lights, a light's type or an Area light's shape changes (light_sync's
depsgraph handler calls ``sync_slots``).
"""

from __future__ import annotations

import bpy

from . import drivers, model_node
from ..core import lights as core_lights
from ..core.model import BY_KEY, LIGHT_SLOTS, light_key

# Blender light settings the model does not follow (docs/model.md "Lights", limits)
UNSUPPORTED = (
    ("normalize", False, "Normalize off"),
    ("use_soft_falloff", False, "Soft Falloff off"),
)


def as_light(obj: bpy.types.Object) -> core_lights.Light:
    """A light object as core.lights.Light (world transform decomposed)."""
    data = obj.data
    loc, rot, scale = obj.matrix_world.decompose()
    extra = {}
    for key in core_lights.PER_TYPE[data.type]:
        extra[key] = getattr(data, key)
    return core_lights.Light(
        type=data.type,
        energy=data.energy,
        name=obj.name,
        location=tuple(loc),
        rotation_euler=tuple(rot.to_euler('XYZ')),
        scale=tuple(scale),
        color=tuple(data.color),
        exposure=getattr(data, "exposure", 0.0),
        use_shadow=bool(data.use_shadow),
        extra=extra,
    )


def new_light_object(light: core_lights.Light, name: str) -> bpy.types.Object:
    """A Blender light object made from core.lights.Light (not linked to a collection)."""
    data = bpy.data.lights.new(name, light.type)
    data.energy = light.energy
    data.color = light.color
    data.exposure = light.exposure
    data.use_shadow = light.use_shadow
    for key in core_lights.PER_TYPE[light.type]:
        setattr(data, key, light.get(key))
    obj = bpy.data.objects.new(name, data)
    obj.location = light.location
    obj.rotation_euler = light.rotation_euler
    obj.scale = light.scale
    return obj


def _rendering_collections(scene: bpy.types.Scene) -> set:
    """The collections of the scene's first view layer that render: not excluded from it and
    neither they nor a parent disabled for rendering (read from the layer collections, which
    are up to date at once; ViewLayer.objects is synced only when the depsgraph updates)."""
    found = set()

    def walk(layer, hidden):
        hidden = hidden or layer.collection.hide_render
        if layer.exclude or hidden:
            return
        found.add(layer.collection)
        for child in layer.children:
            walk(child, hidden)

    if scene.view_layers:
        walk(scene.view_layers[0].layer_collection, False)
    return found


def renders(obj: bpy.types.Object, scene: bpy.types.Scene, collections=None) -> bool:
    """Whether an object renders in the scene's first view layer: not disabled for rendering,
    in a collection that renders (``collections``: _rendering_collections, computed once)."""
    if obj.hide_render:
        return False
    collections = _rendering_collections(scene) if collections is None else collections
    return any(c in collections for c in obj.users_collection)


def scene_lights(scene: bpy.types.Scene, exclude=None) -> list:
    """The light objects the model shades in ``scene``, in slot order, and those left over:
    (used, unused). ``exclude``: the key Sun."""
    collections = _rendering_collections(scene)
    candidates = [
        o
        for o in scene.objects
        if o.type == 'LIGHT'
        and o is not exclude
        and o.data.type in core_lights.TYPES
        and renders(o, scene, collections)
    ]
    order = core_lights.ranked(candidates, key=as_light)
    return order[:LIGHT_SLOTS], order[LIGHT_SLOTS:]


def unsupported(obj: bpy.types.Object) -> list:
    """The light's settings the model does not follow, as labels."""
    data = obj.data
    found = [
        label
        for key, off, label in UNSUPPORTED
        if hasattr(data, key)
        and getattr(data, key) == off
        and (key != "use_soft_falloff" or data.type in ('POINT', 'SPOT'))
    ]
    if data.type == 'AREA' and abs(getattr(data, "spread", 3.14159265) - 3.14159265) > 1e-4:
        found.append("Spread below 180°")
    if obj.matrix_world.determinant() < 0.0:
        found.append("a negative scale")
    return found


def sync_slots(tree: bpy.types.NodeTree, node: bpy.types.Node, objects: list) -> None:
    """Give the model node's slots to ``objects`` (at most LIGHT_SLOTS, in order): each slot's
    values from its light now, its Type, and drivers that keep it in step; the other slots
    are emptied. Drivers on slot inputs must have been removed (model_node.remove_drivers)."""
    for slot in range(1, LIGHT_SLOTS + 1):
        obj = objects[slot - 1] if slot <= len(objects) else None
        model_node.set_light_slot(
            node, slot, core_lights.slot_values(as_light(obj)) if obj is not None else None
        )
        if obj is not None:
            drivers.add_light_drivers(tree, node, slot, obj)


def slot_type(node: bpy.types.Node, slot: int) -> int:
    """The Type a model node's slot holds (0: empty)."""
    name = BY_KEY[light_key(slot, "type")].label
    sock = next((s for s in node.inputs if s.name == name), None)
    return int(sock.default_value) if sock is not None else 0


def state(objects: list) -> tuple:
    """What, changing, needs ``sync_slots`` again (drivers follow the rest)."""
    return tuple((o.name, o.data.type, getattr(o.data, "shape", ""), o.data.name) for o in objects)
