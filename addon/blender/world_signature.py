"""A world node tree as content (``describe``) and its key (``signature``): node types, their
properties, input values and links (node groups followed), image files' content hashes, the
bake's width and the Blender version, so that blender/world_bake.py's cache finds a bake again
exactly when Cycles would render the same world (docs/usage.md, the world bake)."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import bpy

from ..core.errors import UserError
from ..core.hdri import file_hash
from .drivers import world_lighting

KEY_VERSION = 1
_hashes: dict = {}  # (path, size, mtime_ns) -> content hash


_NODE_BASE = {p.identifier for p in bpy.types.ShaderNode.bl_rna.properties} - {"mute"}
_SKIP = {
    "rna_type",
    "name_full",
    "session_uid",
    "is_evaluated",
    "original",
    "users",
    "use_fake_user",
    "use_extra_user",
    "is_embedded_data",
    "is_missing",
    "is_library_indirect",
    "is_runtime_data",
    "tag",
    "is_dirty",
    "preview",
    "library_weak_reference",
    "asset_data",
    "override_library",
    "id_type",
    "bindcode",
    "is_editmode",
    "is_float",
    "has_data",
    "pixels",
    "frame_duration",
    "location",
    "select",
    "show_expanded",
    "select_left_handle",
    "select_right_handle",
    "select_control_point",
}


def _file_hash(path: Path) -> str:
    st = path.stat()
    key = (str(path), st.st_size, st.st_mtime_ns)
    if key not in _hashes:
        _hashes[key] = file_hash(path)
    return _hashes[key]


def image_file(image: bpy.types.Image) -> Path:
    return Path(bpy.path.abspath(image.filepath, library=image.library))


def _image(image: bpy.types.Image, content: bool) -> dict:
    out = {
        "image": image.name,
        "source": image.source,
        "colorspace": image.colorspace_settings.name,
        "alpha": image.alpha_mode,
    }
    if image.packed_file is not None:
        out["packed"] = (
            hashlib.sha256(bytes(image.packed_file.data)).hexdigest()
            if content
            else image.packed_file.size
        )
    elif image.source == 'GENERATED':
        out["generated"] = [
            image.generated_type,
            list(image.generated_color),
            image.generated_width,
            image.generated_height,
            image.use_generated_float,
        ]
    else:
        path = image_file(image)
        if not path.is_file():
            raise UserError(
                f"the world's image {image.name!r} is missing: {path}; relink it "
                "or remove it from the world"
            )
        if content:
            out["sha256"] = _file_hash(path)
        else:
            st = path.stat()
            out["file"] = [str(path), st.st_size, st.st_mtime_ns]
    return out


def _plain(value):
    if value is None or isinstance(value, (bool, int, str)):
        return value
    if isinstance(value, float):
        return repr(value)
    if isinstance(value, (set, frozenset)):
        return sorted(value)
    try:
        return [_plain(v) for v in value]
    except TypeError:
        return repr(value)


class _Describer:
    def __init__(self, content: bool):
        self.content = content
        self.trees: dict = {}

    def id_block(self, block):
        if isinstance(block, bpy.types.Image):
            return _image(block, self.content)
        if isinstance(block, bpy.types.NodeTree):
            if block.name not in self.trees:
                self.trees[block.name] = None  # a group inside itself stops here
                self.trees[block.name] = self.tree(block)
            return {"group": block.name}
        if isinstance(block, bpy.types.Object):
            return {"object": block.name, "matrix": _plain([list(r) for r in block.matrix_world])}
        return {type(block).__name__: block.name}

    def struct(self, s, skip=frozenset(), depth=0):
        if depth > 5:
            return None
        out = {}
        for p in s.bl_rna.properties:
            k = p.identifier
            if k in skip or k in _SKIP or k.startswith("bl_"):
                continue
            try:
                value = getattr(s, k)
            except (AttributeError, RuntimeError):
                continue
            if p.type == 'POINTER':
                if value is None:
                    out[k] = None
                elif isinstance(value, bpy.types.ID):
                    out[k] = self.id_block(value)
                else:
                    out[k] = self.struct(value, depth=depth + 1)
            elif p.type == 'COLLECTION':
                out[k] = [self.struct(v, depth=depth + 1) for v in value]
            else:
                out[k] = _plain(value)
        return out

    def tree(self, tree, unit_strength=None):
        nodes = []
        for node in sorted(tree.nodes, key=lambda n: n.name):
            if node.bl_idname == "NodeFrame":
                continue
            entry = {
                "name": node.name,
                "type": node.bl_idname,
                "props": self.struct(node, _NODE_BASE),
                "inputs": {},
            }
            for sock in node.inputs:
                if hasattr(sock, "default_value"):
                    value = _plain(sock.default_value)
                    if node.name == unit_strength and sock.name == "Strength":
                        value = _plain(1.0)
                    entry["inputs"][sock.identifier] = value
            nodes.append(entry)
        links = sorted(
            [
                l.from_node.name,
                l.from_socket.identifier,
                l.to_node.name,
                l.to_socket.identifier,
                l.is_muted,
                l.is_valid,
            ]
            for l in tree.links
        )
        return {"nodes": nodes, "links": links}


def describe(world: bpy.types.World, width: int = 0, content: bool = True) -> dict:
    """The world's node tree as plain data (the bake's key). ``content``: image files by
    content hash, else by path, size and modification time (cheap: the depsgraph handler's
    change detection)."""
    d = _Describer(content)
    background = world_lighting(world).background
    tree = d.tree(world.node_tree, background.name if background is not None else None)
    return {
        "version": KEY_VERSION,
        "blender": bpy.app.version_string,
        "width": width,
        "tree": tree,
        "groups": d.trees,
    }


def signature(world: bpy.types.World, width: int = 0, content: bool = True) -> str:
    text = json.dumps(describe(world, width, content), sort_keys=True, default=repr)
    return hashlib.sha256(text.encode()).hexdigest()[:24]
