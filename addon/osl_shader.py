"""The OSL shader (osl/cook_torrance.osl) as a Cycles script node.

The source is loaded into an internal text datablock: an installed extension's folder may be
read-only, and external-mode script nodes write the compiled .oso next to the .osl.
"""

from __future__ import annotations

import bpy

from .errors import UserError
from .paths import OSL_DIR

SHADER_FILE = OSL_DIR / "cook_torrance.osl"
TEXT_NAME = "ctlab_cook_torrance.osl"


def ensure_oslquery() -> None:
    """Cycles' script-node update imports oslquery; without Blender's bundled modules exposed,
    the node silently gets no sockets and the material renders black."""
    from .compat import bundled_module
    bundled_module("oslquery")


def shader_text() -> bpy.types.Text:
    """The text datablock holding the shader source, refreshed from osl/ when it differs."""
    source = SHADER_FILE.read_text(encoding="utf-8")
    text = bpy.data.texts.get(TEXT_NAME)
    if text is None:
        text = bpy.data.texts.new(TEXT_NAME)
    if text.as_string() != source:
        text.from_string(source)
    return text


def compile_script_node(node: bpy.types.ShaderNodeScript) -> None:
    """Compile the internal script into the node and create its sockets."""
    ensure_oslquery()
    from cycles import osl as cycles_osl

    node.mode = 'INTERNAL'
    node.script = shader_text()
    errors = []

    def report(kind, message):
        if 'ERROR' in kind:
            errors.append(message)

    cycles_osl.update_script_node(node, report)
    if errors or "BSDF" not in node.outputs:
        raise UserError("the Cook-Torrance OSL shader failed to compile: "
                        + ("; ".join(errors) or "no output socket") + " (see the console)")


def socket(node: bpy.types.Node, identifier: str, output: bool = False) -> bpy.types.NodeSocket:
    """A script node's socket by its OSL parameter name (socket names carry the OSL labels)."""
    for sock in (node.outputs if output else node.inputs):
        if sock.identifier == identifier:
            return sock
    raise KeyError(f"the shader has no parameter {identifier!r}")
