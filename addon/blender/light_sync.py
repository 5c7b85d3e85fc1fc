"""The model's materials follow the scene: the key Sun, the other lights (blender/scene_lights.py)
and the world's strength and rotation through drivers (blender/drivers.py), the world's HDRI
and which light holds which slot through a depsgraph handler (a driver cannot set a file or
choose a light): when the world, its Environment Texture image, the key Sun or the set of lights
(added, removed, hidden from render, a type or shape changed) changes, every user material that
uses the model is synced again, and pointed at the HDRI (or, for a world without an image, a
small uniform image of its colour) and at the files derived from it.
"""

from __future__ import annotations

from pathlib import Path

import bpy

from . import model_node, scene_lights
from .drivers import world_nodes
from ..core import env_importance, ibl_bake
from ..core.errors import UserError
from ..core.hdri import load_hdri, uniform_world
from ..core.model import BY_KEY

MATRIX_TAG = "ctlab_matrix"       # the matrix builder manages its own material (scene_builder)


def key_sun(scene: bpy.types.Scene) -> bpy.types.Object | None:
    """The Sun the model's key light follows: the scene's chosen one (Scene.ctlab_sun), else
    its first Sun light by name that renders, else None (no key light)."""
    chosen = getattr(scene, "ctlab_sun", None)
    if chosen is not None and chosen.type == 'LIGHT' and chosen.data.type == 'SUN' \
            and chosen.name in scene.objects:
        return chosen
    suns = sorted((o for o in scene.objects if o.type == 'LIGHT' and o.data.type == 'SUN'
                   and scene_lights.renders(o, scene)), key=lambda o: o.name)
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
    path = world_hdri_path(scene)
    if path:
        return Path(path)
    return uniform_world(_world_colour(scene.world))


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
            path = environment_file(self.scene)
            load_hdri(path)                  # a clear error for a bad image, once
            self._hdri = path
        return self._hdri

    @property
    def tables(self) -> dict:
        if self._tables is None:
            self._tables = env_importance.tables_for(self.hdri)
        return self._tables

    @property
    def bake(self):
        if self._bake is None:
            self._bake = ibl_bake.bake(self.hdri)
        return self._bake


def update_environment(node: bpy.types.Node, scene: bpy.types.Scene,
                       env: Environment | None = None) -> None:
    """Point the model node at the scene's HDRI and what its indirect-light mode needs: the
    importance tables (reference) or the split-sum bake (baked modes; baked on demand and
    cached by content). A bad HDRI raises UserError. Pass one ``env`` to every node of a
    sync pass."""
    env = env or Environment(scene)
    if model_node.get_option(node, "ibl") == "reference":
        model_node.set_environment(node, env.hdri, tables=env.tables)
    else:
        model_node.set_environment(node, env.hdri, bake=env.bake)


def sync_material(mat: bpy.types.Material, scene: bpy.types.Scene, environment=True,
                  env: Environment | None = None) -> None:
    """Drive a model material's key light from the key Sun, its light slots from the scene's
    other lights (scene_lights) and its world inputs from the world (replacing earlier
    drivers); with ``environment``, also point it at the HDRI (``env``: the sync pass's shared
    Environment)."""
    node = model_node.find(mat)
    if node is None:
        return
    tree = mat.node_tree
    model_node.remove_drivers(tree, node)
    sun = key_sun(scene)
    model_node.add_drivers(tree, node, sun, scene.world)
    if sun is None:                    # no Sun: no key light
        node.inputs[BY_KEY["sun_irradiance"].label].default_value = (0.0, 0.0, 0.0, 1.0)
    used, _unused = scene_lights.scene_lights(scene, exclude=sun)
    scene_lights.sync_slots(tree, node, used)
    if environment:
        update_environment(node, scene, env)


def user_materials():
    """The materials that use the model, but the matrix builder's own."""
    return [(mat, node) for mat, node in model_node.model_materials()
            if not mat.get(MATRIX_TAG)]


def _state(scene) -> tuple:
    world = scene.world
    sun = key_sun(scene)
    used, unused = scene_lights.scene_lights(scene, exclude=sun)
    return (world.name if world else "", world_hdri_path(scene),
            _world_colour(world) if world else (), sun.name if sun else "",
            scene_lights.state(used), len(unused))


_seen: dict = {}               # scene name -> the state last synced
last_error: dict = {}          # scene name -> the last sync error (shown in the panels)


@bpy.app.handlers.persistent
def on_depsgraph_update(scene, depsgraph=None) -> None:
    """Follow a new world, HDRI image or key Sun in every material that uses the model."""
    state = _state(scene)
    if _seen.get(scene.name) == state:
        return
    _seen[scene.name] = state
    last_error.pop(scene.name, None)
    env = Environment(scene)
    for mat, _node in user_materials():
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
