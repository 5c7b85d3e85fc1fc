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
    from . import owned

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
    key = hashlib.sha256(text.as_string().encode()).hexdigest()
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


def set_texture_convention(node: bpy.types.ShaderNodeScript) -> None:
    """Tell the shader how this Blender's OSL texture() counts rows (compat.py); a material
    saved by another Blender version is corrected by light_sync when it syncs."""
    from .compat import osl_texture_rows_bottom_up

    socket(node, "tex_bottom_up").default_value = int(osl_texture_rows_bottom_up())


def set_environment(node: bpy.types.ShaderNodeScript, hdri, bake=None) -> None:
    """Point the shader at the world's HDRI file and, when given, its split-sum bake folder;
    also its width in texels, which the shader needs to filter lat-long images near their
    edges (the bake's level 0 is the HDRI itself, so either file tells it)."""
    from ..core.hdri import image_width
    from ..core.ibl_bake import level_file, tables_folder

    socket(node, "hdri").default_value = str(hdri) if hdri else ""
    socket(node, "tables").default_value = str(tables_folder())
    if bake is not None:
        socket(node, "ibl_bake").default_value = str(bake)
    bake = socket(node, "ibl_bake").default_value
    source = hdri or (Path(bake) / level_file(0) if bake else None)
    socket(node, "hdri_width").default_value = image_width(source) if source else 0


def socket(node: bpy.types.Node, identifier: str, output: bool = False) -> bpy.types.NodeSocket:
    """A script node's socket by its OSL parameter name (socket names carry the OSL labels)."""
    for sock in node.outputs if output else node.inputs:
        if sock.identifier == identifier:
            return sock
    raise KeyError(f"the shader has no parameter {identifier!r}")
