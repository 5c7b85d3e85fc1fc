"""Drivers that keep a model node's key-light and world inputs in step with the scene.

The model's key light is a Sun object: its direction toward the light is the object's world
+Z axis, its irradiance the light's strength x colour. The direction is read as the world-space
rotation quaternion (w, x, y, z) through Transform Channel variables, which the depsgraph
orders after the object's transform (a driver reading matrix_world directly may see it stale):
+Z rotated by q = (2(xz + wy), 2(yz - wx), 1 - 2(x^2 + y^2)). The HDRI's strength and rotation
are the world's Background strength and Mapping Z rotation. Both implementations name these
inputs alike (core.model.LIGHTING), so one set of drivers serves both.
"""

from __future__ import annotations

from typing import NamedTuple

import bpy

from ..core.model import BY_KEY, light_key

SUN_DIRECTION = BY_KEY["sun_to_light"].label
SUN_IRRADIANCE = BY_KEY["sun_irradiance"].label
HDRI_STRENGTH = BY_KEY["hdri_strength"].label
HDRI_ROTATION = BY_KEY["hdri_rotation"].label


def _input_path(node: bpy.types.Node, name: str) -> str:
    index = next(i for i, s in enumerate(node.inputs) if s.name == name)
    return f'nodes["{node.name}"].inputs[{index}].default_value'


def _driver(tree, path, index, expression, variables):
    fcurve = tree.driver_add(path, index) if index is not None else tree.driver_add(path)
    drv = fcurve.driver
    drv.type = 'SCRIPTED'
    for var in list(drv.variables):
        drv.variables.remove(var)
    for name, id_type, ident, data_path in variables:
        var = drv.variables.new()
        var.name = name
        if id_type == 'TRANSFORMS':  # data_path: ROT_W, LOC_X, SCALE_X, ...
            var.type = 'TRANSFORMS'
            target = var.targets[0]
            target.id = ident
            target.transform_type = data_path
            target.rotation_mode = 'QUATERNION'
            target.transform_space = 'WORLD_SPACE'
            continue
        var.type = 'SINGLE_PROP'
        var.targets[0].id_type = id_type
        var.targets[0].id = ident
        var.targets[0].data_path = data_path
    drv.expression = expression  # simple expressions: evaluated without Python
    return fcurve


def remove_drivers(tree: bpy.types.NodeTree, node: bpy.types.Node) -> int:
    """Remove every driver on ``node``'s inputs; returns how many."""
    anim = tree.animation_data
    if anim is None:
        return 0
    prefix = f'nodes["{node.name}"].'
    doomed = [fc for fc in anim.drivers if fc.data_path.startswith(prefix)]
    for fcurve in doomed:
        anim.drivers.remove(fcurve)
    return len(doomed)


def world_nodes(world: bpy.types.World):
    """The world's Background and Mapping nodes (either may be None)."""
    if world is None or world.node_tree is None:
        return None, None
    nodes = world.node_tree.nodes
    background = next((n for n in nodes if n.bl_idname == "ShaderNodeBackground"), None)
    mapping = next((n for n in nodes if n.bl_idname == "ShaderNodeMapping"), None)
    return background, mapping


class WorldLighting(NamedTuple):
    """How a world lights the model (world_lighting).

    kind: "colour" (a uniform image of ``colour``: no world, no node tree, or a Background
    whose Color is not linked; black when nothing reaches the World Output), "image" (the
    Environment Texture ``image_node``'s file is the whole lighting: Environment Texture ->
    Background -> World Output, its vector unlinked or from Generated coordinates through a
    Mapping node that only turns about Z, ``mapping``) or "baked" (any other node tree:
    blender/world_bake.py renders it to an image).
    background: the Background node that feeds the World Output directly with an unlinked
    Strength, whose strength drives HDRI Strength (a baked world is baked at strength 1 of
    it); None when the strength is inside the image (HDRI Strength is then 1).
    mapping: for "image", the Mapping node whose Z rotation drives HDRI Rotation; otherwise
    None (a baked world's rotation is inside the bake: HDRI Rotation is then 0)."""

    kind: str
    background: object = None
    mapping: object = None
    image_node: object = None
    colour: tuple = (0.0, 0.0, 0.0)


def _source(socket):
    """The node and output socket feeding ``socket`` through reroutes, or (None, None)."""
    while socket.is_linked:
        link = socket.links[0]
        if link.is_muted or not link.is_valid:
            return None, None
        node = link.from_node
        if node.bl_idname == "NodeReroute":
            socket = node.inputs[0]
            continue
        return node, link.from_socket
    return None, None


def _plain_mapping(mapping) -> bool:
    """A Mapping node that turns Generated coordinates about Z and nothing else."""
    if mapping.mute or mapping.vector_type != 'POINT':
        return False
    if any(s.is_linked for s in mapping.inputs if s.name != "Vector"):
        return False
    loc, rot, scale = (mapping.inputs[k].default_value for k in ("Location", "Rotation", "Scale"))
    if any(abs(c) > 0 for c in loc) or rot[0] != 0 or rot[1] != 0 or any(c != 1 for c in scale):
        return False
    coords, out = _source(mapping.inputs["Vector"])
    return (
        coords is not None
        and coords.bl_idname == "ShaderNodeTexCoord"
        and not coords.mute
        and out.identifier == "Generated"
    )


def _direct_image(env) -> bool:
    return (
        env.bl_idname == "ShaderNodeTexEnvironment"
        and not env.mute
        and env.image is not None
        and env.image.source == 'FILE'
        and env.projection == 'EQUIRECTANGULAR'
    )


def world_lighting(world: bpy.types.World | None) -> WorldLighting:
    """Classify ``world``'s node tree (WorldLighting). Only the tree's active World Output
    (for Cycles) counts."""
    if world is None:
        return WorldLighting("colour")
    tree = world.node_tree
    if tree is None or (bpy.app.version < (5, 0, 0) and not world.use_nodes):
        return WorldLighting("colour", colour=tuple(world.color))
    output = tree.get_output_node('CYCLES')
    if output is None or output.mute:
        return WorldLighting("colour")
    shader, _ = _source(output.inputs["Surface"])
    if shader is None:
        return WorldLighting("colour")  # nothing reaches the output: black
    if shader.bl_idname != "ShaderNodeBackground" or shader.mute:
        return WorldLighting("baked")
    background = None if shader.inputs["Strength"].is_linked else shader
    colour_socket = shader.inputs["Color"]
    if not colour_socket.is_linked:
        if background is None:
            return WorldLighting("baked")
        return WorldLighting("colour", background, colour=tuple(colour_socket.default_value[:3]))
    env, out = _source(colour_socket)
    if (
        background is not None
        and env is not None
        and _direct_image(env)
        and out.identifier == "Color"
    ):
        vec, vec_out = _source(env.inputs["Vector"])
        if not env.inputs["Vector"].is_linked:
            return WorldLighting("image", background, None, env)
        if (
            vec is not None
            and vec.bl_idname == "ShaderNodeTexCoord"
            and not vec.mute
            and vec_out.identifier == "Generated"
        ):
            return WorldLighting("image", background, None, env)
        if vec is not None and vec.bl_idname == "ShaderNodeMapping" and _plain_mapping(vec):
            return WorldLighting("image", background, vec, env)
    return WorldLighting("baked", background)


def add_drivers(
    tree: bpy.types.NodeTree,
    node: bpy.types.Node,
    sun: bpy.types.Object | None,
    world: bpy.types.World | None,
) -> int:
    """Drive ``node``'s key-light and world inputs from ``sun`` and ``world``; returns how many
    drivers were added. Inputs without a source keep their values, but the world's: HDRI
    Strength follows the Background node that feeds the World Output (world_lighting), else
    is 1 (a world without one, or one whose strength is inside its bake); HDRI Rotation
    follows the Mapping node of an Environment Texture world, else is 0 (a uniform world, or
    one whose rotation is inside its bake)."""
    count = 0
    names = {s.name for s in node.inputs}
    if sun is not None and sun.type == 'LIGHT' and sun.data.type == 'SUN':
        if SUN_DIRECTION in names:
            path = _input_path(node, SUN_DIRECTION)
            quat = [(c, 'TRANSFORMS', sun, f"ROT_{c.upper()}") for c in "wxyz"]
            for i, expr in enumerate(
                ("2 * (x * z + w * y)", "2 * (y * z - w * x)", "1 - 2 * (x * x + y * y)")
            ):
                _driver(tree, path, i, expr, quat)
                count += 1
        if SUN_IRRADIANCE in names:
            path = _input_path(node, SUN_IRRADIANCE)
            for i in range(3):
                _driver(
                    tree,
                    path,
                    i,
                    "e * c",
                    [("e", 'LIGHT', sun.data, "energy"), ("c", 'LIGHT', sun.data, f"color[{i}]")],
                )
                count += 1
    lighting = world_lighting(world)
    background, mapping = lighting.background, lighting.mapping
    if HDRI_STRENGTH in names:
        if background is not None:
            index = next(i for i, s in enumerate(background.inputs) if s.name == "Strength")
            _driver(
                tree,
                _input_path(node, HDRI_STRENGTH),
                None,
                "s",
                [
                    (
                        "s",
                        'WORLD',
                        world,
                        f'node_tree.nodes["{background.name}"].inputs[{index}].default_value',
                    )
                ],
            )
            count += 1
        else:
            node.inputs[HDRI_STRENGTH].default_value = 1.0
    if HDRI_ROTATION in names:
        if mapping is not None:
            index = next(i for i, s in enumerate(mapping.inputs) if s.name == "Rotation")
            _driver(
                tree,
                _input_path(node, HDRI_ROTATION),
                None,
                "r",
                [
                    (
                        "r",
                        'WORLD',
                        world,
                        f'node_tree.nodes["{mapping.name}"].inputs[{index}].default_value[2]',
                    )
                ],
            )
            count += 1
        else:
            node.inputs[HDRI_ROTATION].default_value = 0.0
    return count


# The rotation's columns from the world-space quaternion (w, x, y, z): X, Y and -Z.
_X_AXIS = ("1 - 2 * (y * y + z * z)", "2 * (x * y + w * z)", "2 * (x * z - w * y)")
_Y_AXIS = ("2 * (x * y - w * z)", "1 - 2 * (x * x + z * z)", "2 * (y * z + w * x)")
_MINUS_Z_AXIS = ("-2 * (x * z + w * y)", "-2 * (y * z - w * x)", "2 * (x * x + y * y) - 1")


def add_light_drivers(
    tree: bpy.types.NodeTree, node: bpy.types.Node, slot: int, obj: bpy.types.Object
) -> int:
    """Drive light slot ``slot``'s inputs from a light object, as core.lights.slot_values
    computes them from a light's properties: its world position, -Z axis, power
    (energy x colour x 2^exposure), radius or angle, spot cone, an Area light's half extents
    (size x world scale along X and Y) and its Cast Shadow. The slot's Type is not a driver:
    light_sync sets it (and rebuilds these drivers) when the light's type or shape changes.
    Returns how many drivers were added."""
    names = {s.name for s in node.inputs}
    light = obj.data
    count = 0

    def drive(field, index, expression, variables):
        nonlocal count
        name = BY_KEY[light_key(slot, field)].label
        if name in names:
            _driver(tree, _input_path(node, name), index, expression, variables)
            count += 1

    quat = [(c, 'TRANSFORMS', obj, f"ROT_{c.upper()}") for c in "wxyz"]
    for i, c in enumerate("XYZ"):
        drive("position", i, "p", [("p", 'TRANSFORMS', obj, f"LOC_{c}")])
        drive("direction", i, _MINUS_Z_AXIS[i], quat)
        drive(
            "color",
            i,
            "e * c * pow(2, x)",
            [
                ("e", 'LIGHT', light, "energy"),
                ("c", 'LIGHT', light, f"color[{i}]"),
                ("x", 'LIGHT', light, "exposure"),
            ],
        )
    if light.type == 'AREA':
        rect = light.shape in ('RECTANGLE', 'ELLIPSE')
        for i in range(3):
            drive(
                "axis_x",
                i,
                f"({_X_AXIS[i]}) * 0.5 * s * k",
                quat + [("s", 'LIGHT', light, "size"), ("k", 'TRANSFORMS', obj, "SCALE_X")],
            )
            drive(
                "axis_y",
                i,
                f"({_Y_AXIS[i]}) * 0.5 * s * k",
                quat
                + [
                    ("s", 'LIGHT', light, "size_y" if rect else "size"),
                    ("k", 'TRANSFORMS', obj, "SCALE_Y"),
                ],
            )
    elif light.type == 'SUN':
        drive("size", None, "a", [("a", 'LIGHT', light, "angle")])
    else:
        drive("size", None, "r", [("r", 'LIGHT', light, "shadow_soft_size")])
    if light.type == 'SPOT':
        drive("spot_size", None, "s", [("s", 'LIGHT', light, "spot_size")])
        drive("spot_blend", None, "b", [("b", 'LIGHT', light, "spot_blend")])
    drive("shadow", None, "s", [("s", 'LIGHT', light, "use_shadow")])
    return count
