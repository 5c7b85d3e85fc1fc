"""The model as a network of MaterialX's own pbrlib and stdlib nodes, as data: the one place
that maps the model's inputs and switches onto MaterialX (docs/model.md "The model outside
Blender"). The three exports of ``ctlab export`` are written from it: a ``.mtlx`` document per
material (core/export/materialx.py), a USD layer whose UsdShade materials carry the same
network (core/export/usd.py) and a glTF file of metallic-roughness parameters
(core/export/gltf.py). Pure Python: writing needs no MaterialX.

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

from dataclasses import dataclass, field

from ..model import (
    DIELECTRIC_F0,
    DIFFUSE_MODELS,
    DIFFUSE_SCALE,
    ENERGY_MODES,
    G_MODELS,
    MIN_ALPHA,
    SCENE_EXACT_G,
    UNITS,
)
from .names import ExportNames

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
    """An image file that feeds a surface input, and what lies between them. ``file`` is its
    name inside the export folder (textures/NAME); ``colorspace`` MaterialX's name ("" for
    raw data). Between the image and the input, in this order (core/export/maps.py reads a
    texel so): ``channel`` ("" the colour, "r" its red through a Separate Color node, "a" the
    image's Alpha output); ``invert``, a ``1 - x`` (a roughness map on smoothness); ``scale``,
    a Math Multiply by a constant (Unity's ``_GlossMapScale``); ``tint``, the albedo times a
    constant colour (a Mix node, Multiply: Unity's ``_Color``); ``strength``, a normal map's.
    ``uv_scale`` and ``uv_offset``: a Mapping node (Point) on the UV map, UV * scale +
    offset."""

    file: str
    colorspace: str = ""
    invert: bool = False
    strength: float = 1.0
    channel: str = ""
    scale: float = 1.0
    tint: tuple | None = None
    uv_scale: tuple = (1.0, 1.0)
    uv_offset: tuple = (0.0, 0.0)

    @property
    def uv_mapped(self) -> bool:
        return tuple(self.uv_scale) != (1.0, 1.0) or tuple(self.uv_offset) != (0.0, 0.0)


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
    objects: tuple = ()  # the objects' names (a linked object's: "NAME [LIBRARY]")
    library: str = ""  # the library .blend a linked material comes from ("" local)
    names: ExportNames | None = None  # its names among the materials read with it


def label(mat: Material) -> str:
    """The material's name as a person reads it: a linked one's with its library."""
    return f"{mat.name} [{mat.library}]" if mat.library else mat.name


# What "exact" means for the MaterialX graph (and USD's copy of it): MaterialX's reference GLSL
# multiplies generalized_schlick_bsdf by GGX energy compensation, its OSL hands the closure to
# the renderer, single scattering in Cycles (docs/model.md "The model outside Blender").
EXACT = "exact in Cycles/OSL closures"


def exact(mat: Material) -> bool:
    """Whether the MaterialX graph is the model itself where it is rendered with OSL closures
    like Cycles' (EXACT): Smith's G, energy none (docs/model.md "The closures"); Unity's units
    scale direct light, which no closure does."""
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
    (nodes, {key: node name}). Between an image and its input, as Texture says: the Alpha
    (an ``extract`` of a color4 image), ``1 - x``, the scale and the tint (``multiply``); a
    normal map through ``normalmap``; the UV mapping as the image's ``texcoord``: UV * scale
    + offset (``texcoord``, ``multiply``, ``add``)."""
    nodes, feeds = [], {}
    for key in SURFACE_KEYS:
        tex = mat.textures.get(key)
        if tex is None:
            continue

        def add(name, category, type_, inputs, nodedef_type=None):
            nodedef = f"ND_{category}_{nodedef_type or type_}"
            nodes.append(Node(name, category, type_, nodedef, inputs))
            feeds[key] = name  # noqa: B023  (key: this loop's)
            return name

        kind = {"albedo": "color3", "normal": "vector3"}.get(key, "float")
        image_kind = "color4" if tex.channel == "a" else kind
        inputs = [Input("file", "filename", value=tex.file, colorspace=tex.colorspace)]
        if tex.uv_mapped:  # UV * scale + offset, as Blender's Mapping node (Point)
            uv = add(f"{key}_uv", "texcoord", "vector2", [])
            scale = [_n("in1", "vector2", uv), _v("in2", "vector2", tuple(tex.uv_scale))]
            uv = add(f"{key}_uv_scale", "multiply", "vector2", scale)
            offset = [_n("in1", "vector2", uv), _v("in2", "vector2", tuple(tex.uv_offset))]
            uv = add(f"{key}_uv_offset", "add", "vector2", offset)
            inputs.append(_n("texcoord", "vector2", uv))
        out = add(f"{key}_image", "image", image_kind, inputs)
        if tex.channel == "a":
            alpha = [_n("in", "color4", out), _v("index", "integer", 3)]
            out = add(f"{key}_alpha", "extract", "float", alpha, "color4")
        if key == "normal":
            strength = _v("scale", "float", float(tex.strength))
            add("normal_map", "normalmap", "vector3", [_n("in", "vector3", out), strength], "float")
            continue
        if tex.invert:
            one_minus = [_v("in1", "float", 1.0), _n("in2", "float", out)]
            out = add(f"{key}_invert", "subtract", "float", one_minus)
        if tex.scale != 1.0:
            scaled = [_n("in1", "float", out), _v("in2", "float", float(tex.scale))]
            out = add(f"{key}_scale", "multiply", "float", scaled)
        if key == "albedo" and tex.tint is not None:
            tinted = [_n("in1", "color3", out), _v("in2", "color3", tuple(tex.tint[:3]))]
            add(f"{key}_tint", "multiply", "color3", tinted)
    return nodes, feeds


def interface_values(mat: Material) -> dict:
    """The nodedef's inputs for this material: name -> (type, value) for constants."""
    return {
        "albedo": ("color3", tuple(float(c) for c in mat.albedo[:3])),
        "metallic": ("float", float(mat.metallic)),
        "smoothness": ("float", float(mat.smoothness)),
        "diffuse_lambert": ("integer", int(mat.diffuse_model == "lambert")),
    }
