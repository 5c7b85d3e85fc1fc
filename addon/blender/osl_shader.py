"""The OSL shader (osl/cook_torrance.osl and its parts, inlined by core/osl_source.py) as
a Cycles script node.

The source is loaded into an internal text datablock: an installed extension's folder may be
read-only, and external-mode script nodes write the compiled .oso next to the .osl.
"""

from __future__ import annotations

import hashlib
import re
import tempfile
from pathlib import Path

import bpy

from . import owned
from ..core.errors import UserError
from ..core.files import temporary_folder
from ..core.osl_source import SHADER_FILE, source

TEXT_NAME = "ctlab_cook_torrance.osl"
_COMPILED = {}  # a source's sha256 -> its bytecode, bytecode hash and parameters, this process


def ensure_oslquery() -> None:
    """Cycles' script-node update imports oslquery; without Blender's bundled modules exposed,
    the node silently gets no sockets and the material renders black."""
    from .compat import bundled_module

    bundled_module("oslquery")


def shader_text(path: Path = SHADER_FILE, name: str = TEXT_NAME) -> bpy.types.Text:
    """The add-on's text datablock holding a shader's source (blender/owned.py: a user's
    text of that name is never written; ours is then "<name>.001"), refreshed from its file
    when it differs."""
    text_source = source(path)
    text = owned.find(bpy.data.texts, name, owned.OSL_TEXT)
    if text is None:
        text = owned.new(bpy.data.texts, name, owned.OSL_TEXT)
    if text.as_string() != text_source:
        text.from_string(text_source)
    return text


def compile_script_node(
    node: bpy.types.ShaderNodeScript,
    path: Path = SHADER_FILE,
    name: str = TEXT_NAME,
    output: str = "BSDF",
) -> None:
    """Compile a shader (the model's, by default) as the node's internal script and create
    its sockets."""
    ensure_oslquery()
    from cycles import osl as cycles_osl

    errors = []

    def report(kind, message):
        if 'ERROR' in kind:
            errors.append(message)

    # Cycles compiles an internal script through temporary .osl and .oso files and leaves the
    # .oso (the bytecode is kept in the node), both when we ask and when the node's script
    # is set (its RNA update compiles it, with Cycles as the scene's engine): all of it in a
    # private folder, removed after, and by the cleanup of a signal during the compile
    # (core.files.temporary_folder). Compiled once per process and source: a later node gets
    # the bytecode and the sockets of the first (``_COMPILED``), without a compile (44 ms of
    # a conversion's 78, bench: 300 materials).
    text = shader_text(path, name)
    key = text_digest(text)
    if key in _COMPILED:
        _from_compiled(node, text, *_COMPILED[key])
    else:
        saved = tempfile.tempdir
        with temporary_folder("ctlab-osl-") as folder:
            tempfile.tempdir = str(folder)
            try:
                _set_script(node, text)
                cycles_osl.update_script_node(node, report)
                if node.bytecode and not errors:
                    oso = Path(folder) / "compiled.oso"
                    oso.write_text(node.bytecode)
                    import oslquery

                    params = list(oslquery.OSLQuery(str(oso)).parameters)
                    node.bytecode = portable_bytecode(node.bytecode)
                    node.bytecode_hash = bytecode_hash(node.bytecode)
                    _COMPILED[key] = (node.bytecode, node.bytecode_hash, params)
            finally:
                tempfile.tempdir = saved
    if errors or output not in node.outputs:
        raise UserError(
            f"the OSL shader {Path(path).name} failed to compile: "
            + ("; ".join(errors) or "no output socket")
            + " (see the console)"
        )
    if any(sock.identifier == "tex_bottom_up" for sock in node.inputs):
        set_texture_convention(node)


# A hint of an OSO instruction naming the source file it came from (the compile's temporary
# .osl, Blender's stdosl.h): only where the file changes, for messages.
_FILENAME_HINT = re.compile(r'\s*%filename\{"[^"]*"\}')


def portable_bytecode(bytecode: str) -> str:
    """The compiled shader as a script node stores it, without what oslc adds for a reader:
    its comment lines (the compile's options with this machine's paths, and a copy of each
    source line: about 30% of the model's 0.9 MB) and the instructions' %filename hints (the
    compile's temporary file). The symbols, instructions and their other hints (%line,
    %argrw, %read, %write, ...) are kept as written, so Cycles loads and optimises the same
    shader. A material's bytecode is then smaller in every saved .blend, holds no path of the
    machine that converted it, and is the same for the same source in every process."""
    lines = (line for line in bytecode.split("\n") if not line.startswith("#"))
    return _FILENAME_HINT.sub("", "\n".join(lines))


def bytecode_hash(bytecode: str) -> str:
    """The hash Cycles keys a loaded shader by, computed as Blender's cycles/osl.py does (MD5
    of the bytecode's text)."""
    return hashlib.md5(bytecode.encode()).hexdigest()


def _set_script(node, text) -> None:
    """The node's internal script set without compiling it: while the scene's engine is not
    Cycles, whose RNA update of the script would compile it (we compile once, ourselves)."""
    scene = bpy.context.scene
    engine = scene.render.engine if scene is not None else None
    try:
        if engine == 'CYCLES':
            scene.render.engine = 'BLENDER_WORKBENCH'
        node.mode = 'INTERNAL'
        node.script = text
    finally:
        if engine == 'CYCLES':
            scene.render.engine = engine


def _from_compiled(node, text, bytecode: str, bytecode_hash: str, params: list) -> None:
    """The node given a compiled shader's text, bytecode and sockets, as Cycles' own update
    gives them (cycles/osl.py update_script_node), without compiling."""
    from cycles import osl as cycles_osl

    _set_script(node, text)
    node.bytecode = bytecode
    node.bytecode_hash = bytecode_hash
    used = {cycles_osl.shader_param_ensure(node, param) for param in params} - {None}
    for sockets in (node.inputs, node.outputs):
        for sock in [s for s in sockets if s not in used]:
            sockets.remove(sock)


def set_texture_convention(node: bpy.types.Node) -> None:
    """Tell the shader how this Blender's OSL texture() counts rows (compat.py); a material
    saved by another Blender version is corrected by light_sync when it syncs."""
    from .compat import osl_texture_rows_bottom_up

    socket(node, "tex_bottom_up").default_value = int(osl_texture_rows_bottom_up())


def set_environment(node: bpy.types.Node, hdri, bake=None, files: dict | None = None) -> None:
    """Point the shader at the world's HDRI file and, when given, its split-sum bake folder
    and other ``files`` (string input -> path); also its width in texels, which the shader
    needs to filter lat-long images near their edges (the bake's level 0 is the HDRI itself,
    so either file tells it). The strings change at once (``set_strings``)."""
    from ..core.hdri import image_width
    from ..core.ibl_bake import level_file, tables_folder

    strings = {**(files or {}), "hdri": str(hdri) if hdri else "", "tables": str(tables_folder())}
    if bake is not None:
        strings["ibl_bake"] = str(bake)
    set_strings(node, strings)
    bake = socket(node, "ibl_bake").default_value
    source = hdri or (Path(bake) / level_file(0) if bake else None)
    socket(node, "hdri_width").default_value = image_width(source) if source else 0


def script_node(node: bpy.types.Node) -> bpy.types.ShaderNodeScript | None:
    """The script node of a model node: the node itself, or the one in its group (a group
    carrying the add-on's OSL mark, ``new_group``, also one linked from a library or copied by
    the user); None where the node is neither."""
    if node.bl_idname == "ShaderNodeScript":
        return node
    tree = getattr(node, "node_tree", None)
    if node.bl_idname == "ShaderNodeGroup" and owned.carries_mark(tree, owned.OSL_GROUP):
        return _group_script(tree)
    return None


def socket(node: bpy.types.Node, identifier: str, output: bool = False) -> bpy.types.NodeSocket:
    """A model node's socket by its OSL parameter name (socket names carry the OSL labels):
    a script node's own, or a group node's socket of that name. A string input of a group
    node is its group's script node's, which every material of the group shares: change it
    with ``set_strings``."""
    script = script_node(node) or node
    for sock in script.outputs if output else script.inputs:
        if sock.identifier == identifier:
            if script is node or sock.type == 'STRING':
                return sock
            outer = (node.outputs if output else node.inputs).get(sock.name)
            if outer is None:
                break
            return outer
    raise KeyError(f"the shader has no parameter {identifier!r}")


# --- One compiled shader per file and settings -------------------------------------------------
#
# A script node keeps its compiled shader (628 kB for the model) in the .blend, once per node:
# 20 materials made a 16 MB file. Cycles compiles each material's shader group anyway (it
# specialises it on the constant inputs), so a material needs no copy of its own. The model's
# node is a group node whose group holds the script node: every input but the strings is the
# group's, so each material sets its own; the strings (the view, the switches, the files) stay
# on the script node, as a shader node group has no string socket. Materials whose strings are
# the same share one group, and so one copy of the bytecode. A bare script node (a file of an
# earlier version) keeps working.

GROUP_NAME = "Cook-Torrance Lab OSL"
SCRIPT_NODE = "Cook-Torrance Lab shader"  # the script node's name in the group
SOURCE = "ctlab_osl_source"  # the group's custom property: the sha256 of its script's source
NAME = "ctlab_osl_group_name"  # the group's custom property: the name the add-on gave it
_INTERFACE_TYPES = {
    "VALUE": "NodeSocketFloat",
    "INT": "NodeSocketInt",
    "BOOLEAN": "NodeSocketBool",
    "RGBA": "NodeSocketColor",
    "VECTOR": "NodeSocketVector",
    "SHADER": "NodeSocketShader",
}


def text_digest(text: bpy.types.Text) -> str:
    """The SHA-256 of a shader's source text: the key of its compile (``_COMPILED``) and, for
    the model's, of a shared group's script (``SOURCE``)."""
    return hashlib.sha256(text.as_string().encode()).hexdigest()


_DEFAULTS = {}  # a source's sha256 -> the string inputs of its script node as compiled


def shared_group() -> bpy.types.ShaderNodeTree:
    """A group of the model's current shader for a new model node, its strings the shader's
    defaults (as a new script node's): an existing one of the add-on's (``_mine``), else a copy
    of one with other strings, else a new one. ``set_strings`` then gives the node its own."""
    digest = text_digest(shader_text())
    defaults = _DEFAULTS.get(digest)
    current = [g for g in bpy.data.node_groups if _mine(g) and g.get(SOURCE) == digest]
    if defaults is not None:
        for group in current:
            if _strings(_group_script(group)) == defaults:
                return group
        if current:
            return _copy(current[0], defaults)
    return new_group()


def _group_script(group) -> bpy.types.ShaderNodeScript | None:
    inner = group.nodes.get(SCRIPT_NODE)
    return inner if inner is not None and inner.bl_idname == "ShaderNodeScript" else None


def _mine(group) -> bool:
    """Whether the add-on may change, share or remove ``group``: its OSL mark (not linked), the
    name the add-on gave it (a copy the user makes of it, which keeps the mark, has another
    name: it is the user's), and nothing in it but the group's input, the script node and the
    group's output, linked as ``sync_interface`` links them."""
    if not owned.is_ours(group, owned.OSL_GROUP) or group.get(NAME) != group.name:
        return False
    script = _group_script(group)
    if script is None or len(group.nodes) != 3:
        return False
    if sorted(n.bl_idname for n in group.nodes) != [
        "NodeGroupInput",
        "NodeGroupOutput",
        "ShaderNodeScript",
    ]:
        return False
    expected = len([s for s in script.inputs if s.type != 'STRING']) + len(script.outputs)
    return len(group.links) == expected and all(
        link.from_socket.name == link.to_socket.name
        and (link.to_node == script or link.from_node == script)
        for link in group.links
    )


def _copy(group, strings: dict) -> bpy.types.ShaderNodeTree:
    """A copy of the group, the add-on's, with the given strings."""
    copy = owned.mark(group.copy(), owned.OSL_GROUP)
    copy[NAME] = copy.name
    inner = _group_script(copy)
    for key, value in strings.items():
        inner.inputs[_index(inner, key)].default_value = value
    return copy


def new_group() -> bpy.types.ShaderNodeTree:
    """A new group (marked the add-on's, blender/owned.py) holding the model's script node,
    compiled, with an input for each of its inputs but the strings and an output for each
    output."""
    group = owned.new(bpy.data.node_groups, GROUP_NAME, owned.OSL_GROUP, "ShaderNodeTree")
    group[NAME] = group.name
    group.description = (
        "The Cook-Torrance Lab OSL shader, shared by the materials whose view, switches and "
        "files are the same (docs/usage.md)"
    )
    script = group.nodes.new("ShaderNodeScript")
    script.name = script.label = SCRIPT_NODE
    compile_script_node(script)
    group[SOURCE] = text_digest(script.script)
    _DEFAULTS.setdefault(group[SOURCE], _strings(script))
    sync_interface(group)
    return group


def refresh_group(group) -> None:
    """A group of an earlier shader (a file saved by another version) recompiled in place,
    its interface following the new inputs (a kept input keeps every material's value); a
    linked group is its library's and is left as it is."""
    if not owned.is_ours(group, owned.OSL_GROUP):
        return
    script = _group_script(group)
    previous = {("INPUT", s.name) for s in script.inputs if s.type != 'STRING'}
    previous |= {("OUTPUT", s.name) for s in script.outputs}
    compile_script_node(script)
    group[SOURCE] = text_digest(script.script)
    sync_interface(group, previous)


def sync_interface(group, previous: set = frozenset()) -> None:
    """The group's interface made its script node's: an input for each input but the strings
    and an output for each output, linked; an item that exists under the same name and type
    is kept (with the values the group's nodes give it). Of the others, only those named in
    ``previous`` (the script node's sockets before a recompile) are removed: an item a user
    added stays."""
    script = _group_script(group)
    nodes = group.nodes
    group_in = next((n for n in nodes if n.bl_idname == "NodeGroupInput"), None)
    group_in = group_in or nodes.new("NodeGroupInput")
    group_out = next((n for n in nodes if n.bl_idname == "NodeGroupOutput"), None)
    group_out = group_out or nodes.new("NodeGroupOutput")
    group_in.location, script.location, group_out.location = (-300, 0), (0, 0), (300, 0)
    items = {
        (item.in_out, item.name): item
        for item in group.interface.items_tree
        if item.item_type == 'SOCKET'
    }
    wanted = [("INPUT", s) for s in script.inputs if s.type != 'STRING']
    wanted += [("OUTPUT", s) for s in script.outputs]
    kept = []
    for in_out, sock in wanted:
        kind = _INTERFACE_TYPES[sock.type]
        item = items.pop((in_out, sock.name), None)
        if item is not None and item.socket_type != kind:
            group.interface.remove(item)
            item = None
        if item is None:
            item = group.interface.new_socket(sock.name, in_out=in_out, socket_type=kind)
            if in_out == "INPUT":
                item.default_value = sock.default_value
                item.hide_value = sock.hide_value
        kept.append((in_out, sock, item.identifier))
    for key, item in items.items():
        if key in previous:
            group.interface.remove(item)
    for in_out, sock, identifier in kept:
        if in_out == "INPUT":
            group.links.new(group_in.outputs[identifier], sock)
        else:
            group.links.new(sock, group_out.inputs[identifier])


def _strings(script) -> dict:
    return {s.identifier: s.default_value for s in script.inputs if s.type == 'STRING'}


def _interface(group) -> list:
    """The group's sockets as a group node keeps its values and links by: identifiers."""
    return [
        (i.in_out, i.identifier, i.name, i.socket_type)
        for i in group.interface.items_tree
        if i.item_type == 'SOCKET'
    ]


def set_strings(node: bpy.types.Node, values: dict) -> None:
    """Set a model node's string inputs (OSL parameter name -> text). A script node's are its
    own. A group node gets the group whose strings these are: an existing one of the add-on's
    (``_mine``) of the same shader and sockets, else its own group changed where it is the
    add-on's and no other node uses it, else a copy; the add-on's group that no node uses any
    more is removed. A group that is not the add-on's (the user's copy, a linked one) is never
    changed or removed."""
    script = script_node(node)
    if script is None:
        raise KeyError("not an OSL model node")
    current = _strings(script)
    unknown = set(values) - set(current)
    if unknown:
        raise KeyError(f"the shader has no string parameter {sorted(unknown)[0]!r}")
    wanted = {**current, **{k: str(v) for k, v in values.items()}}
    if script is node:
        for key, value in wanted.items():
            if current[key] != value:
                script.inputs[_index(script, key)].default_value = value
        return
    if wanted == current:
        return
    old = node.node_tree
    same = (old.get(SOURCE), script.bytecode_hash, _interface(old))
    group = next(
        (
            g
            for g in bpy.data.node_groups
            if g is not old
            and _mine(g)
            and (g.get(SOURCE), _group_script(g).bytecode_hash, _interface(g)) == same
            and _strings(_group_script(g)) == wanted
        ),
        None,
    )
    if group is None and _mine(old) and old.users == 1:
        group = old  # only this node uses it: changed in place
        for key, value in wanted.items():
            script.inputs[_index(script, key)].default_value = value
    elif group is None:
        group = _copy(old, wanted)
    if group is not old:
        node.node_tree = group
        if old.users == 0 and _mine(old):
            bpy.data.node_groups.remove(old)


def _index(script, identifier: str) -> int:
    return next(i for i, s in enumerate(script.inputs) if s.identifier == identifier)
