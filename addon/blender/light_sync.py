"""The model's materials follow the scene: the key Sun, the other lights (blender/scene_lights.py)
and the world's strength and rotation through drivers (blender/drivers.py), the world's HDRI
and which light holds which slot through a depsgraph handler (a driver cannot set a file or
choose a light): when the world, its Environment Texture image, the key Sun or the set of lights
(added, removed, hidden from render, a type or shape changed) changes, every user material that
uses the model is synced again, and pointed at the HDRI and at the files derived from it.

The HDRI is the world's Environment Texture file when that image is the world's whole
lighting (drivers.world_lighting: Environment Texture -> Background -> World Output, perhaps
behind a Mapping node); any other node tree (a Sky Texture, gradients, mixes) is baked to an
image (blender/world_bake.py, cached under the tree's content); a world without nodes, or a
Background of one colour, gives a small uniform image of its colour.
"""

from __future__ import annotations

from pathlib import Path

import bpy

from . import model_node, owned, scene_lights, world_bake, world_signature
from .drivers import world_lighting
from ..core import env_importance, ibl_bake
from ..core.errors import UserError
from ..core.hdri import load_hdri, uniform_world
from ..core.model import files_needed

MATRIX_TAG = "ctlab_matrix"  # the matrix builder manages its own material (scene_builder)
RESIDUAL_PASS = "ctlab_residual_pass"  # the scene's custom property: set_residual_pass


def key_sun(scene: bpy.types.Scene) -> bpy.types.Object | None:
    """The Sun the model's key light follows: the scene's chosen one (Scene.ctlab_sun), else
    its first Sun light by name that renders, else None (no key light)."""
    chosen = getattr(scene, "ctlab_sun", None)
    if (
        chosen is not None
        and chosen.type == 'LIGHT'
        and chosen.data.type == 'SUN'
        and chosen.name in scene.objects
        and scene_lights.renders(chosen, scene)
    ):
        return chosen
    suns = sorted(
        (
            o
            for o in scene.objects
            if o.type == 'LIGHT' and o.data.type == 'SUN' and scene_lights.renders(o, scene)
        ),
        key=lambda o: o.name,
    )
    return suns[0] if suns else None


def world_hdri_path(scene: bpy.types.Scene) -> str:
    """The image file of the scene world's Environment Texture when that image is the world's
    whole lighting (drivers.world_lighting "image"), else "" (a baked or uniform world)."""
    lighting = world_lighting(scene.world)
    if lighting.kind != "image":
        return ""
    image = lighting.image_node.image
    return bpy.path.abspath(image.filepath, library=image.library)


def world_label(scene: bpy.types.Scene) -> str:
    """What lights the model, for the panel: "HDRI: forest.exr", "World: baked from its
    nodes (Sky Texture)" or "HDRI: none; the world's colour"."""
    lighting = world_lighting(scene.world)
    if lighting.kind == "image":
        return f"HDRI: {bpy.path.basename(world_hdri_path(scene))}"
    if lighting.kind == "baked":
        return f"World: baked from its nodes ({world_bake.summary(scene.world)})"
    return "HDRI: none; the world's colour"


def environment_file(scene: bpy.types.Scene):
    """The HDRI the model lights with: the world's Environment Texture image when it is the
    whole lighting, the world's node tree baked to an image (world_bake, cached) for any other
    tree, or a small uniform image of the world's colour (kept in the cache)."""
    lighting = world_lighting(scene.world)
    if lighting.kind == "image":
        return Path(world_hdri_path(scene))
    if lighting.kind == "baked":
        return world_bake.bake_world(scene.world)
    return uniform_world(lighting.colour)


def _world_state(world) -> tuple:
    """What of the world the materials depend on, cheaply (the handler runs on every
    depsgraph update): a baked world's tree content, with image files by size and date."""
    lighting = world_lighting(world)
    if lighting.kind == "baked":
        try:
            return ("baked", world_signature.signature(world, content=False))
        except UserError as exc:  # a missing image: sync, which reports it
            return ("baked", str(exc))
    return (lighting.kind, lighting.colour)


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
            load_hdri(path)  # a clear error for a bad image, once
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


def update_environment(
    node: bpy.types.Node, scene: bpy.types.Scene, env: Environment | None = None
) -> None:
    """Point the model node at the scene's HDRI and what its indirect-light mode needs: the
    importance tables (reference) or the split-sum bake (baked modes; baked on demand and
    cached by content). A bad HDRI raises UserError. Pass one ``env`` to every node of a
    sync pass."""
    env = env or Environment(scene)
    need = files_needed(
        model_node.implementation(node),
        model_node.get_option(node, "ibl"),
        model_node.get_option(node, "light_transport"),
    )
    model_node.set_environment(
        node,
        env.hdri,
        tables=env.tables if "tables" in need else None,
        bake=env.bake if "bake" in need else None,
    )


def sync_material(
    mat: bpy.types.Material,
    scene: bpy.types.Scene,
    environment=True,
    env: Environment | None = None,
) -> None:
    """Drive a model material's key light from the key Sun, its light slots from the scene's
    other lights (scene_lights) and its world inputs from the world (replacing earlier
    drivers); with ``environment``, also point it at the HDRI (``env``: the sync pass's shared
    Environment)."""
    node = model_node.find(mat)
    if node is None:
        return
    tree = mat.node_tree
    # The model's emission is a view (lab) or a signed correction (scene), never a lamp:
    # sampled as a mesh light it throws fireflies on its neighbours.
    if mat.cycles.emission_sampling != 'NONE':
        mat.cycles.emission_sampling = 'NONE'
    model_node.set_normal_derivatives(node)  # the user may have linked a normal map
    model_node.remove_drivers(tree, node)
    sun = key_sun(scene)
    model_node.add_drivers(tree, node, sun, scene.world)
    if sun is None:  # no Sun: no key light
        model_node.lighting_input(node, "sun_irradiance").default_value = (0.0, 0.0, 0.0, 1.0)
    used, _unused = scene_lights.scene_lights(scene, exclude=sun)
    scene_lights.sync_slots(tree, node, used)
    if environment:
        update_environment(node, scene, env)
    update_residual(tree, node, scene)


def residual_pass(scene: bpy.types.Scene) -> bool:
    """Whether the scene asks for the residual albedo pass (``set_residual_pass``)."""
    return bool(scene.get(RESIDUAL_PASS, False))


def set_residual_pass(scene: bpy.types.Scene, on: bool) -> None:
    """Ask for the residual albedo pass (Render Properties > Passes > Shader AOV
    residual_albedo) or stop asking: every user material of the scene transport wires its
    model's residual albedo to the pass, or unwires it. Off by default: Cycles' SVM computes
    every node that feeds an AOV Output before it skips a closure, so the pass costs each
    camera hit the correction's tables and lookups even where the correction is zero
    (bench/results.md, "Where the converted product shot's time goes")."""
    scene[RESIDUAL_PASS] = bool(on)
    for mat, node in user_materials():
        update_residual(mat.node_tree, node, scene)


def update_residual(tree: bpy.types.NodeTree, node: bpy.types.Node, scene) -> None:
    """The node's residual albedo wired to the pass where the scene asks for it and the node's
    light transport is the scene's (the lab's residual is zero); unwired otherwise."""
    if residual_pass(scene) and model_node.get_option(node, "light_transport") == "scene":
        model_node.connect_residual(tree, node)
        add_residual_pass(scene)
    else:
        model_node.remove_residual(tree, node)


def add_residual_pass(scene: bpy.types.Scene) -> None:
    """The view layers' AOV for the model's residual albedo (model_node.connect_residual),
    so that it shows as a render pass; added once, never removed."""
    from ..core.model import OSL_RESIDUAL

    for layer in scene.view_layers:
        if OSL_RESIDUAL not in layer.aovs:
            aov = layer.aovs.add()
            aov.name = OSL_RESIDUAL
            aov.type = 'COLOR'


def user_materials():
    """The materials that use the model, but the matrix builder's own and those linked from
    another file (their drivers and images are that file's to change)."""
    return [
        (mat, node)
        for mat, node in model_node.model_materials()
        if not mat.get(MATRIX_TAG) and mat.library is None
    ]


def _state(scene) -> tuple:
    world = scene.world
    sun = key_sun(scene)
    used, unused = scene_lights.scene_lights(scene, exclude=sun)
    return (
        world.name if world else "",
        world_hdri_path(scene),
        _world_state(world),
        sun.name if sun else "",
        scene_lights.state(used),
        len(unused),
    )


_seen: dict = {}  # scene name -> the state last synced
_materials: dict = {}  # scene name -> the names of the file's materials at that sync
last_error: dict = {}  # scene name -> the last sync error (shown in the panels)


@bpy.app.handlers.persistent
def on_depsgraph_update(scene, depsgraph=None) -> None:
    """Follow a new world, HDRI image or key Sun in every material that uses the model, and
    sync a material new to the file (appended from another file, whose drivers follow that
    file's Sun and world, which came along with it) to this scene's."""
    if world_bake.busy():  # the world bake's own scene
        return
    state = _state(scene)
    names = frozenset(bpy.data.materials.keys())
    seen = _materials.get(scene.name)
    if _seen.get(scene.name) == state:
        if seen is None or names <= seen:
            _materials[scene.name] = names
            return
        targets = [(m, n) for m, n in user_materials() if m.name not in seen]
        _materials[scene.name] = names
        if not targets:  # a new material of another kind
            return
    else:
        targets = user_materials()
    _seen[scene.name] = state
    _materials[scene.name] = names
    last_error.pop(scene.name, None)
    env = Environment(scene)
    for mat, _node in targets:
        try:
            sync_material(mat, scene, env=env)
        except UserError as exc:
            last_error[scene.name] = str(exc)
            print(f"Cook-Torrance Lab: {exc}")


@bpy.app.handlers.persistent
def on_load_post(*_args) -> None:
    """The file just opened: the tables and bakes the add-on packed into it are checked
    against the cache's files and packed again where their bytes were changed
    (owned.check_packed_images; a sync checks them too, node_group._float_image)."""
    for name in owned.check_packed_images():
        print(f"Cook-Torrance Lab: the packed image {name!r} differed from its file; packed again")


def register_handler() -> None:
    if on_depsgraph_update not in bpy.app.handlers.depsgraph_update_post:
        bpy.app.handlers.depsgraph_update_post.append(on_depsgraph_update)
    if on_load_post not in bpy.app.handlers.load_post:
        bpy.app.handlers.load_post.append(on_load_post)


def unregister_handler() -> None:
    while on_depsgraph_update in bpy.app.handlers.depsgraph_update_post:
        bpy.app.handlers.depsgraph_update_post.remove(on_depsgraph_update)
    while on_load_post in bpy.app.handlers.load_post:
        bpy.app.handlers.load_post.remove(on_load_post)
    _seen.clear()
    _materials.clear()
    last_error.clear()
