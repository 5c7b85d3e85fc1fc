"""The model as a USD layer (``ctlab export --format usd``): UsdShade materials carrying the
MaterialX network of core/export/network.py, flattened (stdlib and pbrlib nodes only), bound
to prims named like the objects. Pure Python: a ``.usda`` text, no pxr."""

from __future__ import annotations

import json

from .network import Input, Material, Node, exact, interface_values, model_graph
from .network import not_carried, texture_nodes, valid_name
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
    "vector2": "float2",
    "vector3": "float3",
    "integer": "int",
    "boolean": "bool",
    "string": "string",
    "filename": "asset",
    "BSDF": "token",
    "surfaceshader": "token",
}


def _usd_value(type_: str, value) -> str:
    """A value in USD's text: tuples in parentheses, asset paths in @, strings quoted; the
    numbers and booleans as MaterialX writes them (``materialx.mtlx_value``)."""
    if type_ in ("color3", "vector2", "vector3"):
        return "(" + mtlx_value(type_, value) + ")"
    if type_ in ("float", "integer", "boolean"):
        return mtlx_value(type_, value)
    if type_ == "filename":
        return "@" + str(value).replace("@", "") + "@"
    return json.dumps(str(value), ensure_ascii=False)


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
    used, paths = set(), {}
    for mat in materials:
        name = valid_name(mat.name, used)
        paths[mat.name] = f"/Materials/{name}"
        nodes, surface = flat_network(mat)
        what = "exact" if exact(mat) else "closest graph, " + "; ".join(not_carried(mat))
        lines += [
            f'    def Material "{name}" (',
            "        doc = " + json.dumps(mat.name + ": " + what, ensure_ascii=False),
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
                    meta = f' (colorSpace = "{inp.colorspace}")' if inp.colorspace else ""
                    value = _usd_value(inp.type, inp.value)
                    lines.append(f"            {t} inputs:{inp.name} = {value}{meta}")
            lines.append(f"            {USD_TYPES[node.type]} outputs:out")
            lines.append("        }")
        lines.append("    }")
    lines += ["}", "", 'def Scope "Objects"', "{"]
    bound = {}
    for mat in materials:
        for obj in mat.objects:
            bound.setdefault(obj, paths[mat.name])
    used_objects = set()
    for obj, path in sorted(bound.items()):
        name = valid_name(obj, used_objects)
        lines += [
            f'    def Xform "{name}" (',
            '        prepend apiSchemas = ["MaterialBindingAPI"]',
            "        doc = " + json.dumps("object " + obj, ensure_ascii=False),
            "    )",
            "    {",
            f"        rel material:binding = <{path}>",
            "    }",
        ]
    lines += ["}", ""]
    return "\n".join(lines)
