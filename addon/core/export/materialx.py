"""The model as a MaterialX document (``ctlab export --format materialx``): the nodedef
``ND_cook_torrance_lab_surfaceshader`` and its nodegraph (core/export/network.py, the graph
as data), the material's textures, an instance with its values and a surfacematerial.
Pure Python (xml.etree): writing needs no MaterialX."""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET

from .names import fmt_float, utf8_text, valid_name
from .network import NODEDEF_INPUTS, Input, Material, exact, interface_values
from .network import label, model_graph, texture_nodes

MATERIALX_VERSION = "1.39"
NODE = "cook_torrance_lab"
NODEDEF = "ND_cook_torrance_lab_surfaceshader"
NODEGRAPH = "NG_cook_torrance_lab_surfaceshader"


# Characters XML 1.0 cannot hold, even escaped (control characters but tab, newline and
# carriage return; surrogates; U+FFFE and U+FFFF)
_NOT_XML = re.compile("[\x00-\x08\x0b\x0c\x0e-\x1f\ud800-\udfff\ufffe\uffff]")


def xml_text(text) -> str:
    """A user's text as an XML attribute can hold it: undecodable bytes as U+FFFD, characters
    XML 1.0 forbids as U+FFFD (ElementTree escapes the rest: quotes, <, &, newlines)."""
    return _NOT_XML.sub("\ufffd", utf8_text(text))


def mtlx_value(type_: str, value) -> str:
    if type_ in ("color3", "vector2", "vector3"):
        return ", ".join(fmt_float(v) for v in value)
    if type_ == "float":
        return fmt_float(value)
    if type_ == "integer":
        return str(int(value))
    if type_ == "boolean":
        return "true" if value else "false"
    return xml_text(value)


def _mtlx_input(parent, inp: Input, prefix: str = ""):
    e = ET.SubElement(parent, "input", name=inp.name, type=inp.type)
    if inp.node is not None:
        e.set("nodename", prefix + inp.node)
    elif inp.interface is not None:
        e.set("interfacename", inp.interface)
    elif inp.value is not None:
        e.set("value", mtlx_value(inp.type, inp.value))
    if inp.colorspace:
        e.set("colorspace", inp.colorspace)
    return e


def mtlx_document(mat: Material) -> str:
    """A self-contained MaterialX document for one material: the nodedef and nodegraph of the
    model, the material's textures (a nodegraph of image nodes), an instance of the model
    with the material's values, and a surfacematerial."""
    root = ET.Element("materialx", version=MATERIALX_VERSION, colorspace="lin_rec709")
    root.append(
        ET.Comment(
            " Cook-Torrance Lab: Unity's Standard Cook-Torrance BRDF (docs/model.md). "
            + (
                "Exact in Cycles/OSL closures (MaterialX's reference GLSL adds GGX energy "
                "compensation to generalized_schlick_bsdf): "
                if exact(mat)
                else "Closest graph: "
            )
            + f"G {mat.g_model}, diffuse {mat.diffuse_model}, energy {mat.energy}. "
        )
    )
    nd = ET.SubElement(
        root,
        "nodedef",
        name=NODEDEF,
        node=NODE,
        nodegroup="pbr",
        doc="Unity's Standard (BRDF1) Cook-Torrance BRDF as MaterialX pbrlib nodes: GGX, "
        "Schlick F on the specular colour, height-correlated Smith G, Burley or Lambert diffuse",
    )
    for name, type_, default, extra in NODEDEF_INPUTS:
        e = ET.SubElement(nd, "input", name=name, type=type_)
        if default is not None:
            e.set("value", mtlx_value(type_, default))
        for k, v in extra.items():
            e.set(k, v)
    ET.SubElement(nd, "output", name="out", type="surfaceshader")
    ng = ET.SubElement(root, "nodegraph", name=NODEGRAPH, nodedef=NODEDEF)
    for node in model_graph():
        e = ET.SubElement(ng, node.category, name=node.name, type=node.type)
        for inp in node.inputs:
            _mtlx_input(e, inp)
    ET.SubElement(ng, "output", name="out", type="surfaceshader", nodename="surface")

    used = {NODEDEF.casefold(), NODEGRAPH.casefold()}  # valid_name's folded names
    name = valid_name(mat.name, used)
    tex_nodes, feeds = texture_nodes(mat)
    graph_name = valid_name(f"{name}_textures", used) if tex_nodes else None
    if tex_nodes:
        tg = ET.SubElement(root, "nodegraph", name=graph_name)
        for node in tex_nodes:
            e = ET.SubElement(tg, node.category, name=node.name, type=node.type)
            for inp in node.inputs:
                _mtlx_input(e, inp)
        for key, node_name in feeds.items():
            kind = "color3" if key == "albedo" else "vector3" if key == "normal" else "float"
            ET.SubElement(tg, "output", name=f"{key}_out", type=kind, nodename=node_name)
    shader = valid_name(f"{name}_shader", used)
    sh = ET.SubElement(root, NODE, name=shader, type="surfaceshader")
    values = interface_values(mat)
    for key, (type_, value) in values.items():
        e = ET.SubElement(sh, "input", name=key, type=type_)
        if key in feeds:
            e.set("nodegraph", graph_name)
            e.set("output", f"{key}_out")
        else:
            e.set("value", mtlx_value(type_, value))
    if "normal" in feeds:
        ET.SubElement(
            sh, "input", name="normal", type="vector3", nodegraph=graph_name, output="normal_out"
        )
    sm = ET.SubElement(
        root, "surfacematerial", name=name, type="material", doc=xml_text(label(mat))
    )
    ET.SubElement(sm, "input", name="surfaceshader", type="surfaceshader", nodename=shader)
    ET.indent(root, space="  ")
    return '<?xml version="1.0"?>\n' + ET.tostring(root, encoding="unicode") + "\n"
