"""The model as MaterialX (docs/model.md "The model outside Blender"): one place that maps the
model's inputs and switches onto MaterialX's own pbrlib and stdlib nodes, and writes the
three exports of ``ctlab export`` from it: a ``.mtlx`` document per material, a USD layer
(``.usda``) whose UsdShade materials carry the same network, and a glTF file of
metallic-roughness parameters. Pure Python (xml.etree, json): writing needs no MaterialX.

The graph (the nodegraph of the nodedef ``ND_cook_torrance_lab_surfaceshader``), from
docs/model.md "Derived quantities" and "The closures":

- ``pr = 1 - clamp(smoothness)``, ``alpha = max(pr^2, 0.002)`` (core.model.MIN_ALPHA)
- ``specColor = mix(0.04, albedo, metallic)``, ``diffColor = albedo * 0.96 * (1 - metallic)``
- ``generalized_schlick_bsdf(color0 = specColor, color90 = 1, exponent 5, roughness =
  (alpha, alpha), ggx)``: GGX D, Schlick's F (Schlick 1994) and the height-correlated Smith G
  (Heitz 2014, eq. 99), single scattering
- ``burley_diffuse_bsdf(diffColor, pr)`` (Burley 2012, Unity's DisneyDiffuse / pi) or, with the
  switch ``diffuse_lambert`` = 1, ``oren_nayar_diffuse_bsdf(diffColor, 0)`` (Lambert)
- their sum (``add``), as MaterialX's ``surface`` shader.

This is the model exactly for G = smith_ggx_correlated with energy none (either diffuse). For
the Cook-Torrance and Unity G and for compensated energy MaterialX has no closure: the graph
is the same Smith single-scattering lobe, and the difference is the residual tabulated in
docs/model.md (``exact`` says which case a material is).
"""

from __future__ import annotations

import json
import re
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field

from .model import DIFFUSE_MODELS, ENERGY_MODES, G_MODELS, MIN_ALPHA, SCENE_EXACT_G, UNITS

MATERIALX_VERSION = "1.39"
NODE = "cook_torrance_lab"
NODEDEF = "ND_cook_torrance_lab_surfaceshader"
NODEGRAPH = "NG_cook_torrance_lab_surfaceshader"
DIELECTRIC_F0 = 0.04  # docs/model.md: a dielectric's F0 (Unity's unity_ColorSpaceDielectricSpec)
DIFFUSE_SCALE = 1.0 - DIELECTRIC_F0  # diffColor = albedo * 0.96 * (1 - metallic)
# Colour spaces of an image file: Blender's name -> MaterialX's (raw data: none)
COLORSPACES = {
    "sRGB": "srgb_texture",
    "Linear Rec.709": "lin_rec709",
    "Linear": "lin_rec709",
    "Linear CIE-XYZ E": "",
    "Non-Color": "",
    "Raw": "",
}
SURFACE_KEYS = ("albedo", "metallic", "smoothness", "normal")


@dataclass(frozen=True)
class Texture:
    """An image file that feeds a surface input. ``file`` is its name inside the export
    folder (textures/NAME); ``colorspace`` MaterialX's name ("" for raw data); ``invert``: a
    ``1 - x`` between the image and the input (a roughness map on smoothness); ``strength``:
    a normal map's."""

    file: str
    colorspace: str = ""
    invert: bool = False
    strength: float = 1.0


@dataclass(frozen=True)
class Material:
    """One Cook-Torrance material as the export sees it: the surface values (used where no
    texture is wired), the textures, the switches and the objects it is on."""

    name: str
    albedo: tuple = (0.8, 0.8, 0.8)
    metallic: float = 0.0
    smoothness: float = 0.5
    g_model: str = G_MODELS[0]
    diffuse_model: str = DIFFUSE_MODELS[0]
    energy: str = ENERGY_MODES[0]
    units: str = UNITS[0]
    textures: dict = field(default_factory=dict)  # key of SURFACE_KEYS -> Texture
    objects: tuple = ()


def exact(mat: Material) -> bool:
    """Whether the MaterialX graph is the model itself: Smith's G, energy none (docs/model.md
    "The closures"); Unity's units scale direct light, which no closure does."""
    return mat.g_model == SCENE_EXACT_G and mat.energy == ENERGY_MODES[0] and mat.units == UNITS[0]


def not_carried(mat: Material) -> list:
    """What of the material the MaterialX graph does not carry, in words."""
    out = []
    if mat.g_model != SCENE_EXACT_G:
        out.append(f"G {mat.g_model} (written as height-correlated Smith)")
    if mat.energy != ENERGY_MODES[0]:
        out.append(f"energy {mat.energy} (written as single scattering)")
    if mat.units != UNITS[0]:
        out.append(f"units {mat.units} (written as physical)")
    return out


# ---------------------------------------------------------------------------------------
# The graph, as data: nodes whose inputs hold a value, a node's output or an interface name


@dataclass
class Input:
    name: str
    type: str
    value: object = None
    node: str | None = None  # the output of this node (in the same graph)
    interface: str | None = None  # the nodedef's input of this name
    colorspace: str = ""


@dataclass
class Node:
    name: str
    category: str
    type: str
    nodedef: str
    inputs: list


def _v(name, type_, value):
    return Input(name, type_, value=value)


def _n(name, type_, node):
    return Input(name, type_, node=node)


def _i(name, type_, interface):
    return Input(name, type_, interface=interface)


# The nodedef's inputs: (name, type, default, extra attributes)
NODEDEF_INPUTS = (
    ("albedo", "color3", (0.8, 0.8, 0.8), {"doc": "base colour, linear RGB"}),
    ("metallic", "float", 0.0, {"doc": "metalness"}),
    ("smoothness", "float", 0.5, {"doc": "Unity's smoothness: 1 - perceptual roughness"}),
    ("normal", "vector3", None, {"defaultgeomprop": "Nworld"}),
    (
        "diffuse_lambert",
        "integer",
        0,
        {"uniform": "true", "doc": "0: Burley's (Disney) diffuse, 1: Lambert"},
    ),
)


def model_graph() -> list:
    """The nodegraph's nodes (docstring of this module), inputs by interface name."""
    return [
        Node("albedo_c", "clamp", "color3", "ND_clamp_color3", [_i("in", "color3", "albedo")]),
        Node("metallic_c", "clamp", "float", "ND_clamp_float", [_i("in", "float", "metallic")]),
        Node("smoothness_c", "clamp", "float", "ND_clamp_float", [_i("in", "float", "smoothness")]),
        Node(
            "pr",
            "subtract",
            "float",
            "ND_subtract_float",
            [_v("in1", "float", 1.0), _n("in2", "float", "smoothness_c")],
        ),
        Node(
            "pr2",
            "multiply",
            "float",
            "ND_multiply_float",
            [_n("in1", "float", "pr"), _n("in2", "float", "pr")],
        ),
        Node(
            "alpha",
            "max",
            "float",
            "ND_max_float",
            [_n("in1", "float", "pr2"), _v("in2", "float", MIN_ALPHA)],
        ),
        Node(
            "roughness",
            "combine2",
            "vector2",
            "ND_combine2_vector2",
            [_n("in1", "float", "alpha"), _n("in2", "float", "alpha")],
        ),
        Node(
            "spec_color",
            "mix",
            "color3",
            "ND_mix_color3",
            [
                _n("fg", "color3", "albedo_c"),
                _v("bg", "color3", (DIELECTRIC_F0,) * 3),
                _n("mix", "float", "metallic_c"),
            ],
        ),
        Node(
            "one_minus_metallic",
            "subtract",
            "float",
            "ND_subtract_float",
            [_v("in1", "float", 1.0), _n("in2", "float", "metallic_c")],
        ),
        Node(
            "diffuse_weight",
            "multiply",
            "float",
            "ND_multiply_float",
            [_n("in1", "float", "one_minus_metallic"), _v("in2", "float", DIFFUSE_SCALE)],
        ),
        Node(
            "diff_color",
            "multiply",
            "color3",
            "ND_multiply_color3FA",
            [_n("in1", "color3", "albedo_c"), _n("in2", "float", "diffuse_weight")],
        ),
        Node(
            "specular",
            "generalized_schlick_bsdf",
            "BSDF",
            "ND_generalized_schlick_bsdf",
            [
                _n("color0", "color3", "spec_color"),
                _v("color82", "color3", (1.0, 1.0, 1.0)),
                _v("color90", "color3", (1.0, 1.0, 1.0)),
                _v("exponent", "float", 5.0),
                _n("roughness", "vector2", "roughness"),
                _i("normal", "vector3", "normal"),
                _v("distribution", "string", "ggx"),
            ],
        ),
        Node(
            "disney",
            "burley_diffuse_bsdf",
            "BSDF",
            "ND_burley_diffuse_bsdf",
            [
                _n("color", "color3", "diff_color"),
                _n("roughness", "float", "pr"),
                _i("normal", "vector3", "normal"),
            ],
        ),
        Node(
            "lambert",
            "oren_nayar_diffuse_bsdf",
            "BSDF",
            "ND_oren_nayar_diffuse_bsdf",
            [
                _n("color", "color3", "diff_color"),
                _v("roughness", "float", 0.0),
                _i("normal", "vector3", "normal"),
            ],
        ),
        Node(
            "use_lambert",
            "ifequal",
            "float",
            "ND_ifequal_floatI",
            [
                _i("value1", "integer", "diffuse_lambert"),
                _v("value2", "integer", 1),
                _v("in1", "float", 1.0),
                _v("in2", "float", 0.0),
            ],
        ),
        Node(
            "diffuse",
            "mix",
            "BSDF",
            "ND_mix_bsdf",
            [
                _n("fg", "BSDF", "lambert"),
                _n("bg", "BSDF", "disney"),
                _n("mix", "float", "use_lambert"),
            ],
        ),
        Node(
            "bsdf",
            "add",
            "BSDF",
            "ND_add_bsdf",
            [_n("in1", "BSDF", "specular"), _n("in2", "BSDF", "diffuse")],
        ),
        Node("surface", "surface", "surfaceshader", "ND_surface", [_n("bsdf", "BSDF", "bsdf")]),
    ]


def texture_nodes(mat: Material) -> tuple:
    """The material's texture nodes and, per surface input, the node that feeds it:
    (nodes, {key: node name})."""
    nodes, feeds = [], {}
    for key in SURFACE_KEYS:
        tex = mat.textures.get(key)
        if tex is None:
            continue
        kind = {"albedo": "color3", "normal": "vector3"}.get(key, "float")
        image = f"{key}_image"
        nodes.append(
            Node(
                image,
                "image",
                kind,
                f"ND_image_{kind}",
                [Input("file", "filename", value=tex.file, colorspace=tex.colorspace)],
            )
        )
        feeds[key] = image
        if key == "normal":
            nodes.append(
                Node(
                    "normal_map",
                    "normalmap",
                    "vector3",
                    "ND_normalmap_float",
                    [_n("in", "vector3", image), _v("scale", "float", float(tex.strength))],
                )
            )
            feeds[key] = "normal_map"
        elif tex.invert:
            nodes.append(
                Node(
                    f"{key}_invert",
                    "subtract",
                    "float",
                    "ND_subtract_float",
                    [_v("in1", "float", 1.0), _n("in2", "float", image)],
                )
            )
            feeds[key] = f"{key}_invert"
    return nodes, feeds


def interface_values(mat: Material) -> dict:
    """The nodedef's inputs for this material: name -> (type, value) for constants."""
    return {
        "albedo": ("color3", tuple(float(c) for c in mat.albedo[:3])),
        "metallic": ("float", float(mat.metallic)),
        "smoothness": ("float", float(mat.smoothness)),
        "diffuse_lambert": ("integer", int(mat.diffuse_model == "lambert")),
    }


# ---------------------------------------------------------------------------------------
# Names and values


_INVALID = re.compile(r"[^A-Za-z0-9_]")


def valid_name(text: str, used: set) -> str:
    """A MaterialX element name and USD prim name from ``text`` (letters, digits and
    underscores, not starting with a digit), unique among ``used`` (which it joins)."""
    base = _INVALID.sub("_", str(text)) or "material"
    if base[0].isdigit():
        base = "_" + base
    name, i = base, 1
    while name in used:
        i += 1
        name = f"{base}_{i}"
    used.add(name)
    return name


def _fmt(x: float) -> str:
    return f"{float(x):.9g}"


def mtlx_value(type_: str, value) -> str:
    if type_ in ("color3", "vector2", "vector3"):
        return ", ".join(_fmt(v) for v in value)
    if type_ == "float":
        return _fmt(value)
    if type_ == "integer":
        return str(int(value))
    if type_ == "boolean":
        return "true" if value else "false"
    return str(value)


# ---------------------------------------------------------------------------------------
# MaterialX


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
            + ("Exact: " if exact(mat) else "Closest graph: ")
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

    used = {NODEDEF, NODEGRAPH}
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
    sm = ET.SubElement(root, "surfacematerial", name=name, type="material")
    ET.SubElement(sm, "input", name="surfaceshader", type="surfaceshader", nodename=shader)
    ET.indent(root, space="  ")
    return '<?xml version="1.0"?>\n' + ET.tostring(root, encoding="unicode") + "\n"


# ---------------------------------------------------------------------------------------
# USD: the same network, flattened (stdlib and pbrlib nodes only), bound to prims named
# like the objects


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
    if type_ in ("color3", "vector2", "vector3"):
        return "(" + ", ".join(_fmt(v) for v in value) + ")"
    if type_ == "float":
        return _fmt(value)
    if type_ == "integer":
        return str(int(value))
    if type_ == "boolean":
        return "true" if value else "false"
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


# ---------------------------------------------------------------------------------------
# glTF 2.0: metallic-roughness parameters (docs/model.md "The model outside Blender")


def metallic_roughness_name(mat: Material) -> str | None:
    """The glTF metallic-roughness image a material needs (textures/NAME), or None: glTF
    packs roughness in G and metallic in B of one image (``metallic_roughness_pixels``)."""
    if "metallic" not in mat.textures and "smoothness" not in mat.textures:
        return None
    return f"textures/{valid_name(mat.name, set())}_metallic_roughness.png"


def metallic_roughness_pixels(metallic, smoothness, invert: bool):
    """glTF's metallic-roughness image from the model's maps (numpy arrays of one channel,
    or None where the input is a value, carried by the factor): G = roughness = 1 -
    smoothness (the map itself when it fed smoothness through ``1 - x``), B = metallic, R = 1
    (unused). Maps of different sizes are sampled at the larger one's texel centres."""
    import numpy as np

    maps = [m for m in (metallic, smoothness) if m is not None]
    h = max(m.shape[0] for m in maps)
    w = max(m.shape[1] for m in maps)

    def at_size(m):
        if m is None:
            return np.ones((h, w), np.float32)
        rows = ((np.arange(h) + 0.5) * m.shape[0] / h).astype(int)
        cols = ((np.arange(w) + 0.5) * m.shape[1] / w).astype(int)
        return m[rows][:, cols].astype(np.float32)

    rough = at_size(smoothness)
    if smoothness is not None and not invert:
        rough = 1.0 - rough
    return np.stack([np.ones((h, w), np.float32), rough, at_size(metallic)], axis=-1)


def _f7(x) -> float:
    """A float32 value as its 7 significant digits (0.8, not 0.800000011920929)."""
    return float(f"{float(x):.7g}")


def gltf_material(mat: Material, texture_index) -> dict:
    """glTF's core material for the model's values: baseColorFactor = albedo, metallicFactor
    = metallic, roughnessFactor = 1 - smoothness (glTF's roughness is perceptual, squared to
    GGX's alpha like the model's pr); the albedo, normal and metallic-roughness textures (a
    factor is 1 where its texture holds the values). ``texture_index(file)`` gives a
    texture's index in the file. The switches glTF cannot carry go to extras."""
    pbr = {
        "baseColorFactor": [_f7(c) for c in mat.albedo[:3]] + [1.0],
        "metallicFactor": _f7(mat.metallic),
        "roughnessFactor": _f7(1.0 - float(mat.smoothness)),
    }
    out = {"name": mat.name, "pbrMetallicRoughness": pbr}
    if "albedo" in mat.textures:
        pbr["baseColorFactor"] = [1.0, 1.0, 1.0, 1.0]
        pbr["baseColorTexture"] = {"index": texture_index(mat.textures["albedo"].file)}
    packed = metallic_roughness_name(mat)
    if packed is not None:
        pbr["metallicRoughnessTexture"] = {"index": texture_index(packed)}
        if "metallic" in mat.textures:
            pbr["metallicFactor"] = 1.0
        if "smoothness" in mat.textures:
            pbr["roughnessFactor"] = 1.0
    if "normal" in mat.textures:
        tex = mat.textures["normal"]
        out["normalTexture"] = {"index": texture_index(tex.file), "scale": _f7(tex.strength)}
    out["extras"] = {
        "cook_torrance_lab": {
            "g_model": mat.g_model,
            "diffuse_model": mat.diffuse_model,
            "energy": mat.energy,
            "units": mat.units,
            "albedo": [_f7(c) for c in mat.albedo[:3]],
            "smoothness": _f7(mat.smoothness),
            "not_carried": gltf_not_carried(mat),
        }
    }
    return out


def gltf_not_carried(mat: Material) -> list:
    """What glTF's core material (GGX, height-correlated Smith, Schlick F, Lambert diffuse,
    F0 0.04 with a (1 - F) weighted diffuse) leaves out of this material."""
    out = not_carried(mat)
    if mat.diffuse_model != "lambert":
        out.append("Burley (Disney) diffuse (glTF's diffuse is Lambert)")
    return out


def gltf_document(materials: list) -> dict:
    """A minimal glTF 2.0 file holding the materials (no meshes)."""
    images, textures, index = [], [], {}

    def texture_index(file: str) -> int:
        if file not in index:
            images.append({"uri": file})
            textures.append({"source": len(images) - 1})
            index[file] = len(textures) - 1
        return index[file]

    doc = {
        "asset": {"version": "2.0", "generator": "Cook-Torrance Lab (ctlab export)"},
        "materials": [gltf_material(m, texture_index) for m in materials],
    }
    if images:
        doc["images"], doc["textures"] = images, textures
    return doc
