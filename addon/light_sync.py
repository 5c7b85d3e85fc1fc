"""Drivers that keep a Cook-Torrance node's key light and world inputs in sync with the scene.

The model's key light is a Sun object: its direction toward the light is the object's world
+Z axis, its irradiance the light's strength x colour. The direction is read as the world-space
rotation quaternion (w, x, y, z) through Transform Channel variables, which the depsgraph
orders after the object's transform (a driver reading matrix_world directly may see it stale):
+Z rotated by q = (2(xz + wy), 2(yz - wx), 1 - 2(x^2 + y^2)). The HDRI's
strength and rotation are the world's Background strength and Mapping Z rotation. The node
group and the OSL script node both name these inputs "Sun Direction", "Sun Irradiance",
"HDRI Strength" and "HDRI Rotation", so one set of drivers serves both.

A driver cannot set a file path, so the HDRI itself (the world's Environment Texture image, or
the world's colour when it has none) reaches the materials through ``update_environment``,
which a depsgraph handler runs when the world's image, the world or the key Sun changes.
"""

from __future__ import annotations

import bpy

DRIVEN = ("Sun Direction", "Sun Irradiance", "HDRI Strength", "HDRI Rotation")


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
        if id_type == 'TRANSFORMS':              # data_path: ROT_W, ROT_X, ...
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
    drv.expression = expression          # simple expressions: evaluated without Python
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


def add_drivers(tree: bpy.types.NodeTree, node: bpy.types.Node, sun: bpy.types.Object | None,
                world: bpy.types.World | None) -> int:
    """Drive ``node``'s key-light and world inputs from ``sun`` and ``world``; returns how many
    drivers were added. Inputs without a source keep their values."""
    count = 0
    names = {s.name for s in node.inputs}
    if sun is not None and sun.type == 'LIGHT' and sun.data.type == 'SUN':
        if "Sun Direction" in names:
            path = _input_path(node, "Sun Direction")
            quat = [(c, 'TRANSFORMS', sun, f"ROT_{c.upper()}") for c in "wxyz"]
            for i, expr in enumerate(("2 * (x * z + w * y)", "2 * (y * z - w * x)",
                                      "1 - 2 * (x * x + y * y)")):
                _driver(tree, path, i, expr, quat)
                count += 1
        if "Sun Irradiance" in names:
            path = _input_path(node, "Sun Irradiance")
            for i in range(3):
                _driver(tree, path, i, "e * c", [("e", 'LIGHT', sun.data, "energy"),
                                                  ("c", 'LIGHT', sun.data, f"color[{i}]")])
                count += 1
    background, mapping = world_nodes(world)
    if background is not None and "HDRI Strength" in names:
        _driver(tree, _input_path(node, "HDRI Strength"), None, "s",
                [("s", 'WORLD', world, f'node_tree.nodes["{background.name}"].inputs[1].default_value')])
        count += 1
    if mapping is not None and "HDRI Rotation" in names:
        _driver(tree, _input_path(node, "HDRI Rotation"), None, "r",
                [("r", 'WORLD', world, f'node_tree.nodes["{mapping.name}"].inputs[2].default_value[2]')])
        count += 1
    return count


# ----------------------------------------------------------------------------------------
# User materials: the key Sun, the world's HDRI, and the handler that follows them

def key_sun(scene: bpy.types.Scene) -> bpy.types.Object | None:
    """The Sun the model's key light follows: the scene's chosen one (Scene.ctlab_sun), else
    its first Sun light by name, else None (no key light)."""
    chosen = getattr(scene, "ctlab_sun", None)
    if chosen is not None and chosen.type == 'LIGHT' and chosen.data.type == 'SUN' \
            and chosen.name in scene.objects:
        return chosen
    suns = sorted((o for o in scene.objects if o.type == 'LIGHT' and o.data.type == 'SUN'),
                  key=lambda o: o.name)
    return suns[0] if suns else None


def world_hdri_path(scene: bpy.types.Scene) -> str:
    """The image file of the scene world's Environment Texture, or "" when there is none."""
    world = scene.world
    if world is None or world.node_tree is None:
        return ""
    for node in world.node_tree.nodes:
        if node.bl_idname == "ShaderNodeTexEnvironment" and node.image is not None:
            return bpy.path.abspath(node.image.filepath, library=node.image.library)
    return ""


def _world_colour(world) -> tuple:
    background, _ = world_nodes(world)
    if background is not None:
        return tuple(background.inputs["Color"].default_value[:3])
    return tuple(world.color) if world is not None else (0.0, 0.0, 0.0)


def environment_file(scene: bpy.types.Scene):
    """The HDRI the model lights with: the world's Environment Texture image, or, for a world
    without one, a small uniform image of the world's colour (kept in the cache)."""
    from pathlib import Path
    path = world_hdri_path(scene)
    if path:
        return Path(path)
    import numpy as np
    from .hdri import write_float_exr
    from .paths import cache_dir
    colour = _world_colour(scene.world)
    target = cache_dir() / ("uniform-%.6g-%.6g-%.6g.exr" % colour)
    if not target.is_file():
        write_float_exr(target, np.broadcast_to(np.float32(colour), (8, 16, 3)).copy())
    return target


class Environment:
    """The scene's HDRI and what the materials derive from it, each resolved once however
    many materials a sync pass updates: the file (validated), its importance tables and its
    split-sum bake (both cached by content on disk, but each lookup hashes the file)."""

    def __init__(self, scene: bpy.types.Scene):
        self.scene = scene
        self._hdri = self._tables = self._bake = None

    @property
    def hdri(self):
        if self._hdri is None:
            from .hdri import load_hdri
            path = environment_file(self.scene)
            load_hdri(path)                  # a clear error for a bad image, once
            self._hdri = path
        return self._hdri

    @property
    def tables(self) -> dict:
        if self._tables is None:
            from . import env_importance
            self._tables = env_importance.tables_for(self.hdri)
        return self._tables

    @property
    def bake(self):
        if self._bake is None:
            from . import ibl_bake
            self._bake = ibl_bake.bake(self.hdri)
        return self._bake


def update_environment(node: bpy.types.Node, scene: bpy.types.Scene,
                       env: Environment | None = None) -> None:
    """Point the model node at the scene's HDRI: its path and importance tables (OSL,
    reference IBL) or its baked split-sum files (baked IBL modes; the node group's textures).
    Bakes on demand (cached by content): a bad HDRI raises UserError. Pass one ``env`` to
    every node of a sync pass."""
    from . import model_node, osl_shader
    env = env or Environment(scene)
    ibl = model_node.get_option(node, "ibl")
    if model_node.implementation(node) == "osl":
        osl_shader.set_texture_convention(node)        # a file saved by another Blender
        sock = lambda ident: osl_shader.socket(node, ident)  # noqa: E731
        if ibl == "reference":
            sock("env_marginal").default_value = env.tables["marginal"]
            sock("env_conditional").default_value = env.tables["conditional"]
            sock("env_pdf_table").default_value = env.tables["pdf"]
            osl_shader.set_environment(node, env.hdri)
        else:
            osl_shader.set_environment(node, env.hdri, env.bake)
    else:
        from .node_group import set_bake
        set_bake(node.node_tree, env.bake)


def sync_material(mat: bpy.types.Material, scene: bpy.types.Scene, environment=True,
                  env: Environment | None = None) -> None:
    """Drive a model material's key light from the key Sun and its HDRI inputs from the
    world (replacing earlier drivers); with ``environment``, also point it at the HDRI
    (``env``: the sync pass's shared Environment)."""
    from . import model_node
    node = model_node.find(mat)
    if node is None:
        return
    tree = mat.node_tree
    remove_drivers(tree, node)
    sun = key_sun(scene)
    add_drivers(tree, node, sun, scene.world)
    if sun is None:                    # no Sun: no key light
        node.inputs["Sun Irradiance"].default_value = (0.0, 0.0, 0.0, 1.0)
    if environment:
        update_environment(node, scene, env)


def _state(scene) -> tuple:
    world = scene.world
    sun = key_sun(scene)
    return (world.name if world else "", world_hdri_path(scene),
            _world_colour(world) if world else (), sun.name if sun else "")


_seen: dict = {}               # scene name -> the state last synced
last_error: dict = {}          # scene name -> the last sync error (shown in the panels)


@bpy.app.handlers.persistent
def on_depsgraph_update(scene, depsgraph=None) -> None:
    """Follow a new world, HDRI image or key Sun in every material that uses the model."""
    from . import model_node
    from .errors import UserError
    state = _state(scene)
    if _seen.get(scene.name) == state:
        return
    _seen[scene.name] = state
    last_error.pop(scene.name, None)
    env = Environment(scene)
    for mat, _node in list(model_node.model_materials()):
        if mat.get("ctlab_matrix"):          # the matrix builder manages its own material
            continue
        try:
            sync_material(mat, scene, env=env)
        except UserError as exc:
            last_error[scene.name] = str(exc)
            print(f"Cook-Torrance Lab: {exc}")


def register_handler() -> None:
    if on_depsgraph_update not in bpy.app.handlers.depsgraph_update_post:
        bpy.app.handlers.depsgraph_update_post.append(on_depsgraph_update)


def unregister_handler() -> None:
    while on_depsgraph_update in bpy.app.handlers.depsgraph_update_post:
        bpy.app.handlers.depsgraph_update_post.remove(on_depsgraph_update)
    _seen.clear()
    last_error.clear()
