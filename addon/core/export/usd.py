"""The model as a USD layer (``ctlab export --format usd``): UsdShade materials carrying the
MaterialX network of core/export/network.py, flattened (stdlib and pbrlib nodes only), bound
to prims named like the objects. Pure Python: a ``.usda`` text, no pxr."""

from __future__ import annotations

import unicodedata

from .names import export_names, utf8_text, valid_name
from .network import EXACT, Input, Material, Node, exact, interface_values
from .network import label, model_graph, not_carried, texture_nodes
from .materialx import mtlx_value


def flat_network(mat: Material) -> tuple:
    """The model's graph with the material's values and textures in place of its interface:
    (nodes, name of the surface node). Any reader that knows MaterialX's standard library can
    use it; it needs no nodedef of ours."""
    tex_nodes, feeds = texture_nodes(mat)
    values = interface_values(mat)
    nodes = list(tex_nodes)
    for node in model_graph():
        inputs = []
        for inp in node.inputs:
            if inp.interface is None:
                inputs.append(inp)
            elif inp.interface in feeds:
                inputs.append(Input(inp.name, inp.type, node=feeds[inp.interface]))
            elif inp.interface in values:
                inputs.append(Input(inp.name, inp.type, value=values[inp.interface][1]))
            # an unconnected normal: the geometry's (the nodedef's default geomprop)
        nodes.append(Node(node.name, node.category, node.type, node.nodedef, inputs))
    return nodes, "surface"


USD_TYPES = {
    "float": "float",
    "color3": "color3f",
    "color4": "color4f",
    "vector2": "float2",
    "vector3": "float3",
    "integer": "int",
    "boolean": "bool",
    "string": "string",
    "filename": "asset",
    "BSDF": "token",
    "surfaceshader": "token",
}


# USD's text escapes (pxr's TfEscapeString reads them back): a backslash, the quote and the
# control characters; any other character, non-ASCII included, is written as it is (UTF-8).
_ESCAPES = {"\\": "\\\\", '"': '\\"', "\n": "\\n", "\r": "\\r", "\t": "\\t"}


def usd_string(text) -> str:
    """``text`` as a USD string literal (double quotes), read back exactly by USD's parser:
    a backslash, a quote, newline, carriage return and tab escaped, other control characters
    (and DEL) as ``\\xHH``; undecodable bytes (a non-UTF-8 file name) as U+FFFD."""
    out = []
    for c in utf8_text(text):
        if c in _ESCAPES:
            out.append(_ESCAPES[c])
        elif ord(c) < 0x20 or ord(c) == 0x7F:
            out.append(f"\\x{ord(c):02x}")
        else:
            out.append(c)
    return '"' + "".join(out) + '"'


def usd_asset(path) -> str:
    """An asset path in USD's text: ``@path@``, or ``@@@path@@@`` when it holds an ``@``
    (``@@@`` inside escaped as ``\\@@@``); control characters (C0, DEL, C1), which no asset
    path can hold, are dropped, undecodable bytes become U+FFFD; non-ASCII is written as it
    is."""
    text = "".join(c for c in utf8_text(path) if unicodedata.category(c) != "Cc")
    if "@" not in text:
        return "@" + text + "@"
    return "@@@" + text.replace("@@@", "\\@@@") + "@@@"


def _usd_value(type_: str, value) -> str:
    """A value in USD's text: tuples in parentheses, asset paths in @, strings quoted; the
    numbers and booleans as MaterialX writes them (``materialx.mtlx_value``)."""
    if type_ in ("color3", "vector2", "vector3"):
        return "(" + mtlx_value(type_, value) + ")"
    if type_ in ("float", "integer", "boolean"):
        return mtlx_value(type_, value)
    if type_ == "filename":
        return usd_asset(value)
    return usd_string(value)


def usda_document(materials: list) -> str:
    """A USD layer (text) with a UsdShade Material per model material under /Materials, each
    carrying the flattened MaterialX network (outputs:mtlx:surface), and a prim per object
    under /Objects named like the object, bound to its material (MaterialBindingAPI). No
    geometry: a pipeline layers it over its own by path. The default prim is /Materials (a
    reference to the file brings the material library)."""
    lines = [
        "#usda 1.0",
        "(",
        '    doc = "Cook-Torrance Lab export: the model as MaterialX networks (docs/model.md)"',
        '    defaultPrim = "Materials"',
        '    upAxis = "Z"',
        "    metersPerUnit = 1",
        ")",
        "",
        'def Scope "Materials"',
        "{",
    ]
    materials = list(materials)
    paths = []  # by the material's place in the list: two materials may share a name
    for mat, names in zip(materials, export_names(materials)):
        name = names.ident
        paths.append(f"/Materials/{name}")
        nodes, surface = flat_network(mat)
        what = EXACT if exact(mat) else "closest graph, " + "; ".join(not_carried(mat))
        lines += [
            f'    def Material "{name}" (',
            "        doc = " + usd_string(label(mat) + ": " + what),
            "        customData = {",
            "            string blender_name = " + usd_string(mat.name),
            "            string blender_library = " + usd_string(mat.library),
            "        }",
            "    )",
            "    {",
            "        token outputs:mtlx:surface.connect = "
            f"</Materials/{name}/{surface}.outputs:out>",
        ]
        for node in nodes:
            lines += [f'        def Shader "{node.name}"', "        {"]
            lines.append(f'            uniform token info:id = "{node.nodedef}"')
            for inp in node.inputs:
                t = USD_TYPES[inp.type]
                if inp.node is not None:
                    lines.append(
                        f"            {t} inputs:{inp.name}.connect = "
                        f"</Materials/{name}/{inp.node}.outputs:out>"
                    )
                elif inp.value is not None:
                    meta = f" (colorSpace = {usd_string(inp.colorspace)})" if inp.colorspace else ""
                    value = _usd_value(inp.type, inp.value)
                    lines.append(f"            {t} inputs:{inp.name} = {value}{meta}")
            lines.append(f"            {USD_TYPES[node.type]} outputs:out")
            lines.append("        }")
        lines.append("    }")
    lines += ["}", "", 'def Scope "Objects"', "{"]
    bound = {}
    for mat, path in zip(materials, paths):
        for obj in mat.objects:
            bound.setdefault(obj, path)
    used_objects = set()
    for obj, path in sorted(bound.items()):
        name = valid_name(obj, used_objects)
        lines += [
            f'    def Xform "{name}" (',
            '        prepend apiSchemas = ["MaterialBindingAPI"]',
            "        doc = " + usd_string("object " + obj),
            "        customData = {",
            "            string blender_name = " + usd_string(obj),
            "        }",
            "    )",
            "    {",
            f"        rel material:binding = <{path}>",
            "    }",
        ]
    lines += ["}", ""]
    return "\n".join(lines)
