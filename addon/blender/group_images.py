"""The node group's images: the baked split-sum files (core/ibl_bake.py) and the scene
transport's tables (core/correction_tables.py) that its texture nodes read (tagged by
blender/node_compiler.py: BAKE_FILE, BAKE_DIM, MODEL_TABLE), packed into the file so that it
renders without the add-on, and checked against their files when used (blender/owned.py).
Used through blender/node_group.py, which assembles the groups.
"""

from __future__ import annotations

import os
from pathlib import Path

import bpy

from ..core.correction_tables import correction_table_folder
from ..core.errors import UserError
from . import owned
from .node_compiler import BAKE_DIM, BAKE_FILE, MODEL_TABLE
from .owned import CORRECTION_GROUP, LIGHT_GROUP, NODE_GROUP, TABLE_IMAGE


def set_bake(group: bpy.types.ShaderNodeTree, folder) -> None:
    """Point the group's texture nodes at a bake folder's files (core/ibl_bake.py), and the
    scene transport's tables at theirs (``correction_table_folder``, once per cache)."""
    folder = Path(folder)
    trees, pending = [], [group]  # and the groups it holds: per-light, correction
    while pending:
        tree = pending.pop()
        if tree not in trees:
            trees.append(tree)
            pending += [
                n.node_tree
                for n in tree.nodes
                if n.bl_idname == "ShaderNodeGroup"
                and n.node_tree is not None
                and (n.node_tree.get(LIGHT_GROUP) or n.node_tree.get(CORRECTION_GROUP))
            ]
    nodes = [node for tree in trees for node in tree.nodes]
    tables = correction_table_folder() if any(MODEL_TABLE in node for node in nodes) else None
    for node in nodes:
        # unchanged values are not set again: every change re-syncs each material using
        # the group (0.8 s a material, growing with the materials, where a conversion set
        # the shared group's bake again for each)
        if MODEL_TABLE in node:
            image = _float_image(tables / f"{node[MODEL_TABLE]}.exr")
            if node.image != image:
                node.image = image
        if BAKE_FILE not in node:
            continue
        path = folder / f"{node[BAKE_FILE]}.exr"
        if not path.is_file():
            raise UserError(f"the bake folder {folder} has no {path.name}; bake again")
        image = _float_image(path)
        if BAKE_DIM in node:
            size = float(image.size[0 if node[BAKE_DIM] == "width" else 1])
            if node.outputs[0].default_value != size:
                node.outputs[0].default_value = size
        elif node.image != image:
            node.image = image


def table_images() -> set:
    """The images the model's groups read (their tables and bakes, set_bake), in any file:
    the add-on makes them again from its cache when a material syncs."""
    return {
        node.image
        for group in bpy.data.node_groups
        if group.get(NODE_GROUP) or group.get(LIGHT_GROUP) or group.get(CORRECTION_GROUP)
        for node in group.nodes
        if (BAKE_FILE in node or MODEL_TABLE in node) and getattr(node, "image", None)
    }


def _float_image(path: Path) -> bpy.types.Image:
    """A baked file or table as an image, packed into the .blend (Image.pack): the file
    renders the same on a machine without the add-on or its cache (a render farm), since
    Cycles and EEVEE read a packed image's own bytes. The image keeps the cache path, which
    need not exist there. Only an image of the add-on's (owned.TABLE_IMAGE) is reused, once
    its packed bytes are checked against the file (owned.packed_intact): bytes changed in the
    .blend are packed again from the cache."""
    want = os.path.normpath(path)
    image = next(
        (
            i
            for i in bpy.data.images
            if owned.is_ours(i, TABLE_IMAGE)
            and os.path.normpath(bpy.path.abspath(i.filepath)) == want  # saved as //...
        ),
        None,
    )
    if image is None:
        image = owned.mark(bpy.data.images.load(want), TABLE_IMAGE)
    if image.colorspace_settings.name != "Non-Color":  # setting it reloads the image
        image.colorspace_settings.name = "Non-Color"
    if image.use_half_precision:
        image.use_half_precision = False  # EEVEE: keep 32-bit floats on the GPU
    if image.packed_file is None:
        image.pack()
    elif not owned.packed_intact(image, path):
        owned.repack(image)
    return image
