"""Build the Cook-Torrance node group from its description, node_groups/cook_torrance.toml.

The description is data: frames of named nodes written as nested calls (see the file's header).
This module parses each expression into Blender shader nodes, wires them, puts each frame's
nodes into a frame named after the term, and selects the view with the View input. The group's
sockets are the model's interface (core.model.GROUP_INPUTS). The baked split-sum files
(core/ibl_bake.py) are loaded as images by ``set_bake``.
"""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

import bpy

from ..core.errors import UserError
from ..core.files import NODE_GROUPS_DIR
from ..core.ibl_bake import DFG_SIZE, LEVEL_COUNT
from ..core.model import GROUP_INPUTS, GROUP_OUTPUTS, VIEWS

DESCRIPTION = NODE_GROUPS_DIR / "cook_torrance.toml"
TAG = "ctlab_node_group"
BAKE_FILE = "ctlab_bake_file"           # texture nodes: which baked file they read
BAKE_DIM = "ctlab_bake_dim"             # value nodes: that file's width or height


SOCKET_TYPES = {"FLOAT": "NodeSocketFloat", "INT": "NodeSocketInt", "RGBA": "NodeSocketColor",
                "VECTOR": "NodeSocketVector", "SHADER": "NodeSocketShader"}
VECTOR_VALUE_OPS = {"DOT_PRODUCT", "LENGTH", "DISTANCE"}


def load_description(path: Path = DESCRIPTION) -> dict:
    with open(path, "rb") as f:
        data = tomllib.load(f)
    if list(data["views"]) != list(VIEWS):
        raise UserError(f"{path}: the views must be, in order: {', '.join(VIEWS)}")
    if data["group"]["dfg_size"] != DFG_SIZE:
        raise UserError(f"{path}: its DFG lookups are written for {data['group']['dfg_size']}"
                        f"-texel tables; ibl_bake makes {DFG_SIZE}")
    return data


# --- Parsing -----------------------------------------------------------------------------

_TOKEN = re.compile(r"\s*(?:(?P<num>-?\d+\.?\d*(?:[eE][-+]?\d+)?)|(?P<name>[A-Za-z_][\w. !]*?)"
                    r"(?=\s*[(),]|\s*$)|(?P<sym>[(),]))")


def parse(text: str):
    """'KIND.OP(a, b)' -> ('call', 'KIND.OP', [args]); names -> ('ref', name); numbers ->
    ('num', value). Names may hold spaces (group inputs such as ``in.Sun Direction``)."""
    tokens = []
    pos = 0
    while pos < len(text):
        m = _TOKEN.match(text, pos)
        if not m or m.end() == pos:
            if text[pos:].strip() == "":
                break
            raise UserError(f"node description: cannot parse {text!r} at {text[pos:]!r}")
        pos = m.end()
        kind = m.lastgroup
        tokens.append((kind, m.group(kind).strip()))

    def expr(i):
        kind, value = tokens[i]
        if kind == "num":
            return ("num", float(value)), i + 1
        if kind != "name":
            raise UserError(f"node description: unexpected {value!r} in {text!r}")
        if i + 1 < len(tokens) and tokens[i + 1] == ("sym", "("):
            args, i = [], i + 2
            while tokens[i] != ("sym", ")"):
                arg, i = expr(i)
                args.append(arg)
                if tokens[i] == ("sym", ","):
                    i += 1
            return ("call", value, args), i + 1
        return ("ref", value), i + 1

    tree, end = expr(0)
    if end != len(tokens):
        raise UserError(f"node description: trailing text in {text!r}")
    return tree


# --- Building ----------------------------------------------------------------------------

class _Builder:
    def __init__(self, tree: bpy.types.ShaderNodeTree, data: dict):
        self.tree = tree
        self.nodes = tree.nodes
        self.data = data
        self.exprs = {}                     # node name -> (frame, parsed expression)
        for frame, spec in data["frames"].items():
            for name, text in spec["nodes"].items():
                self.exprs[name] = (frame, parse(text))
        self.built = {}                     # node name -> output socket
        self.frames = {}
        self.current_frame = None
        self.group_in = self.nodes.new("NodeGroupInput")
        self.geometry = None
        self.columns = {}

    def frame(self, key):
        if key not in self.frames:
            f = self.nodes.new("NodeFrame")
            f.name = f"frame_{key}"
            f.label = self.data["frames"][key]["label"] if key in self.data["frames"] else key
            f.label_size = 14
            self.frames[key] = f
        return self.frames[key]

    def new(self, idname, **props):
        node = self.nodes.new(idname)
        for k, v in props.items():
            setattr(node, k, v)
        frame = self.frame(self.current_frame)
        node.parent = frame
        col = self.columns.setdefault(self.current_frame, 0)
        self.columns[self.current_frame] += 1
        index = list(self.frames).index(self.current_frame)
        node.location = (200 * (col % 12), -1200 * index - 160 * (col // 12))
        return node

    def link(self, value, sock):
        if isinstance(value, bpy.types.NodeSocket):
            self.tree.links.new(value, sock)
        elif sock.type == 'VECTOR' or sock.type == 'RGBA':
            n = len(sock.default_value)
            sock.default_value = (value,) * n if n == 3 else (value, value, value, 1.0)
        else:
            sock.default_value = value

    def socket(self, name):
        """The output socket of a named node, a group input or a geometry output."""
        if name.startswith("in."):
            return self.group_in.outputs[name[3:]]
        if name.startswith("geo."):
            if self.geometry is None:
                self.geometry = self.nodes.new("ShaderNodeNewGeometry")
                self.geometry.location = (-400, 0)
            return self.geometry.outputs[name[4:]]
        if name in self.built:
            return self.built[name]
        if name not in self.exprs:
            raise UserError(f"node description: unknown name {name!r}")
        frame, tree = self.exprs[name]
        saved, self.current_frame = self.current_frame, frame
        sock = self.value(tree)
        self.current_frame = saved
        if isinstance(sock, bpy.types.NodeSocket):
            sock.node.label = name
        self.built[name] = sock
        return sock

    def value(self, tree):
        kind = tree[0]
        if kind == "num":
            return tree[1]
        if kind == "ref":
            return self.socket(tree[1])
        _, op, args = tree
        if op in ("env", "table"):          # the first argument names a baked file
            return self.call(op, [args[0][1]] + [self.value(a) for a in args[1:]])
        return self.call(op, [self.value(a) for a in args])

    def call(self, op, args):
        if op.startswith("math."):
            oper = op[5:]
            clamp = oper.endswith("!")
            node = self.new("ShaderNodeMath", operation=oper.rstrip("!"), use_clamp=clamp)
            for i, a in enumerate(args):
                self.link(a, node.inputs[i])
            return node.outputs[0]
        if op.startswith("vec."):
            oper = op[4:]
            node = self.new("ShaderNodeVectorMath", operation=oper)
            if oper == "SCALE":
                self.link(args[0], node.inputs[0])
                self.link(args[1], node.inputs["Scale"])
            else:
                for i, a in enumerate(args):
                    self.link(a, node.inputs[i])
            return node.outputs["Value" if oper in VECTOR_VALUE_OPS else "Vector"]
        if op == "vec3":
            node = self.new("ShaderNodeCombineXYZ")
            for i, a in enumerate(args):
                self.link(a, node.inputs[i])
            return node.outputs[0]
        if op in ("x", "y", "z"):
            node = self.new("ShaderNodeSeparateXYZ")
            self.link(args[0], node.inputs[0])
            return node.outputs[op.upper()]
        if op in ("pick", "vpick"):
            c, a, b = args
            kind = "math" if op == "pick" else "vec"
            not_c = self.call("math.SUBTRACT", [1.0, c])
            if kind == "math":
                return self.call("math.ADD", [self.call("math.MULTIPLY", [a, not_c]),
                                              self.call("math.MULTIPLY", [b, c])])
            return self.call("vec.ADD", [self.call("vec.SCALE", [a, not_c]),
                                         self.call("vec.SCALE", [b, c])])
        if op == "rotz":
            node = self.new("ShaderNodeVectorRotate", rotation_type='Z_AXIS')
            self.link(args[0], node.inputs["Vector"])
            self.link(args[1], node.inputs["Angle"])
            return node.outputs[0]
        if op == "env":
            # Blender's equirectangular mapping (the Environment Texture's, image rows bottom-up):
            # s = 0.5 - atan2(d.y, d.x) / 2pi,  t = 0.5 + atan2(d.z, hypot(d.x, d.y)) / pi
            d = args[1]
            dx, dy, dz = (self.call(c, [d]) for c in ("x", "y", "z"))
            s = self.call("math.SUBTRACT", [0.5, self.call("math.DIVIDE", [
                self.call("math.ARCTAN2", [dy, dx]), 6.283185307179586])])
            hyp = self.call("math.SQRT", [self.call("math.ADD", [
                self.call("math.MULTIPLY", [dx, dx]), self.call("math.MULTIPLY", [dy, dy])])])
            t = self.call("math.ADD", [0.5, self.call("math.DIVIDE", [
                self.call("math.ARCTAN2", [dz, hyp]), 3.141592653589793])])
            return self.bilinear(args[0], s, t, wrap_s=True)
        if op == "table":
            return self.bilinear(args[0], args[1], args[2], wrap_s=False)
        if op == "levels":
            x, direction = args
            total = None
            for k in range(LEVEL_COUNT):
                # hat weight max(0, 1 - |x - k|): the two neighbouring levels, blended linearly
                w = self.call("math.MAXIMUM", [self.call("math.SUBTRACT", [
                    1.0, self.call("math.ABSOLUTE", [self.call("math.SUBTRACT", [x, float(k)])])]),
                    0.0])
                term = self.call("vec.SCALE", [self.call("env", [f"specular_{k}", direction]), w])
                total = term if total is None else self.call("vec.ADD", [total, term])
            return total
        raise UserError(f"node description: unknown operation {op!r}")

    def bilinear(self, key, s, t, wrap_s):
        """Bilinear interpolation of a baked image at (s, t) from four nearest-texel lookups at
        texel centres, as OIIO's "linear" texture() in the OSL shader: s periodic (or clamped),
        t clamped. Written out because EEVEE's linear sampling uses mip-maps chosen by screen
        derivatives, which blur the tables and levels; nearest lookups have none."""
        size = []
        for dim in ("width", "height"):
            value = self.new("ShaderNodeValue")
            value.label = f"{key} {dim}"
            value[BAKE_FILE] = key
            value[BAKE_DIM] = dim
            value.outputs[0].default_value = 1.0
            size.append(value.outputs[0])
        W, H = size
        x = self.call("math.SUBTRACT", [self.call("math.MULTIPLY", [s, W]), 0.5])
        y = self.call("math.SUBTRACT", [self.call("math.MULTIPLY", [t, H]), 0.5])
        i0 = self.call("math.FLOOR", [x])
        j0 = self.call("math.FLOOR", [y])
        fx = self.call("math.SUBTRACT", [x, i0])
        fy = self.call("math.SUBTRACT", [y, j0])
        half_h = self.call("math.DIVIDE", [0.5, H])

        def centre_u(i):
            return self.call("math.DIVIDE", [self.call("math.ADD", [i, 0.5]), W])

        def centre_v(j):
            v = self.call("math.DIVIDE", [self.call("math.ADD", [j, 0.5]), H])
            return self.call("math.MINIMUM", [self.call("math.MAXIMUM", [v, half_h]),
                                              self.call("math.SUBTRACT", [1.0, half_h])])
        us = (centre_u(i0), centre_u(self.call("math.ADD", [i0, 1.0])))
        vs = (centre_v(j0), centre_v(self.call("math.ADD", [j0, 1.0])))
        wx = (self.call("math.SUBTRACT", [1.0, fx]), fx)
        wy = (self.call("math.SUBTRACT", [1.0, fy]), fy)
        total = None
        for a in range(2):
            for b in range(2):
                node = self.new("ShaderNodeTexImage", interpolation='Closest',
                                extension='REPEAT' if wrap_s else 'EXTEND')
                node.label = key
                node[BAKE_FILE] = key
                self.link(self.call("vec3", [us[a], vs[b], 0.0]), node.inputs["Vector"])
                term = self.call("vec.SCALE", [node.outputs["Color"],
                                               self.call("math.MULTIPLY", [wx[a], wy[b]])])
                total = term if total is None else self.call("vec.ADD", [total, term])
        return total


def _interface(group):
    """The group's sockets: the model's interface (core.model), in its order."""
    group.interface.clear()
    for i in GROUP_INPUTS:
        sock = group.interface.new_socket(i.group, in_out='INPUT',
                                          socket_type=SOCKET_TYPES[i.kind])
        sock.description = i.tooltip
        if i.kind in ("FLOAT", "INT"):
            cast = int if i.kind == "INT" else float
            sock.default_value, sock.min_value, sock.max_value = \
                cast(i.default), cast(i.min), cast(i.max)
        else:
            sock.default_value = i.default
        if i.key == "normal":
            sock.hide_value = True
    for name, kind in GROUP_OUTPUTS:
        group.interface.new_socket(name, in_out='OUTPUT', socket_type=SOCKET_TYPES[kind])


def build_group(name: str | None = None) -> bpy.types.ShaderNodeTree:
    """The node group, built anew from node_groups/cook_torrance.toml (an existing group of
    the same name made by this add-on is rebuilt in place, so materials keep using it)."""
    data = load_description()
    name = name or data["group"]["name"]
    group = bpy.data.node_groups.get(name)
    if group is None or group.bl_idname != "ShaderNodeTree":
        group = bpy.data.node_groups.new(name, "ShaderNodeTree")
    group[TAG] = True
    group.description = data["group"]["description"]
    group.nodes.clear()
    _interface(group)
    b = _Builder(group, data)
    b.group_in.location = (-600, 0)
    # the views, selected by the View input: sum over k of (View == k) x view_k
    b.current_frame = "views"
    b.frames["views"] = b.frame("views")
    b.frames["views"].label = "View (term isolation)"
    total = None
    for k, (view, text) in enumerate(data["views"].items()):
        value = b.value(parse(text))
        b.current_frame = "views"
        on = b.call("math.COMPARE", [b.socket("in.View"), float(k), 0.5])
        term = b.call("vec.SCALE", [value, on])
        total = term if total is None else b.call("vec.ADD", [total, term])
    emission = b.new("ShaderNodeEmission")
    b.link(total, emission.inputs["Color"])
    emission.inputs["Strength"].default_value = 1.0
    out = group.nodes.new("NodeGroupOutput")
    out.location = (2800, 0)
    group.links.new(emission.outputs["Emission"], out.inputs["Emission"])
    group.links.new(total, out.inputs["Value"])
    return group


SOURCE_HASH = "ctlab_source_hash"


def ensure_group() -> bpy.types.ShaderNodeTree:
    """The node group, reused when it was built from the current description (rebuilding
    would reset the inputs and links of every material using it), else built."""
    import hashlib
    digest = hashlib.sha256(DESCRIPTION.read_bytes() + repr(GROUP_INPUTS).encode()
                            ).hexdigest()[:16]
    group = bpy.data.node_groups.get(load_description()["group"]["name"])
    if group is not None and group.get(TAG) and group.get(SOURCE_HASH) == digest:
        return group
    group = build_group()
    group[SOURCE_HASH] = digest
    return group


def set_bake(group: bpy.types.ShaderNodeTree, folder) -> None:
    """Point the group's texture nodes at a bake folder's files (addon/ibl_bake.py)."""
    folder = Path(folder)
    for node in group.nodes:
        if BAKE_FILE not in node:
            continue
        path = folder / f"{node[BAKE_FILE]}.exr"
        if not path.is_file():
            raise UserError(f"the bake folder {folder} has no {path.name}; bake again")
        image = bpy.data.images.load(str(path), check_existing=True)
        image.colorspace_settings.name = "Non-Color"
        image.use_half_precision = False        # EEVEE: keep 32-bit floats on the GPU
        if BAKE_DIM in node:
            node.outputs[0].default_value = float(image.size[0 if node[BAKE_DIM] == "width" else 1])
        else:
            node.image = image
