"""Build the Cook-Torrance node group from its description, node_groups/cook_torrance.toml.

The description is data: frames of named nodes written as nested calls (see the file's header).
This module parses each expression into Blender shader nodes, wires them, puts each frame's
nodes into a frame named after the term, and selects the view with the View input. The baked
split-sum files (addon/ibl_bake.py) are loaded as images by ``set_bake``.
"""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

import bpy

from .errors import UserError
from .params import VIEWS
from .paths import PACKAGE_ROOT

DESCRIPTION = PACKAGE_ROOT / "node_groups" / "cook_torrance.toml"
TAG = "ctlab_node_group"
BAKE_FILE = "ctlab_bake_file"           # texture nodes: which baked file they read
LEVELS = 7

SOCKET_TYPES = {"FLOAT": "NodeSocketFloat", "INT": "NodeSocketInt", "RGBA": "NodeSocketColor",
                "VECTOR": "NodeSocketVector", "SHADER": "NodeSocketShader"}
VECTOR_VALUE_OPS = {"DOT_PRODUCT", "LENGTH", "DISTANCE"}


def load_description(path: Path = DESCRIPTION) -> dict:
    with open(path, "rb") as f:
        data = tomllib.load(f)
    if list(data["views"]) != list(VIEWS):
        raise UserError(f"{path}: the views must be, in order: {', '.join(VIEWS)}")
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
            node = self.new("ShaderNodeTexEnvironment", interpolation='Linear',
                            projection='EQUIRECTANGULAR')
            node.label = args[0]
            node[BAKE_FILE] = args[0]
            self.link(args[1], node.inputs["Vector"])
            return node.outputs["Color"]
        if op == "table":
            uv = self.call("vec3", [args[1], args[2], 0.0])
            node = self.new("ShaderNodeTexImage", interpolation='Linear', extension='EXTEND')
            node.label = args[0]
            node[BAKE_FILE] = args[0]
            self.link(uv, node.inputs["Vector"])
            return node.outputs["Color"]
        if op == "levels":
            x, direction = args
            total = None
            for k in range(LEVELS):
                # hat weight max(0, 1 - |x - k|): the two neighbouring levels, blended linearly
                w = self.call("math.MAXIMUM", [self.call("math.SUBTRACT", [
                    1.0, self.call("math.ABSOLUTE", [self.call("math.SUBTRACT", [x, float(k)])])]),
                    0.0])
                term = self.call("vec.SCALE", [self.call("env", [f"specular_{k}", direction]), w])
                total = term if total is None else self.call("vec.ADD", [total, term])
            return total
        raise UserError(f"node description: unknown operation {op!r}")


def _interface(group, data):
    group.interface.clear()
    for name, kind, default, lo, hi, tip in data["group"]["inputs"]:
        sock = group.interface.new_socket(name, in_out='INPUT', socket_type=SOCKET_TYPES[kind])
        sock.description = tip
        if kind in ("FLOAT", "INT"):
            sock.default_value, sock.min_value, sock.max_value = default, lo, hi
        else:
            sock.default_value = default
        if name == "Normal":
            sock.hide_value = True
    for name, kind in data["group"]["outputs"]:
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
    _interface(group, data)
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


def set_bake(group: bpy.types.ShaderNodeTree, folder) -> None:
    """Point the group's texture nodes at a bake folder's files (addon/ibl_bake.py)."""
    folder = Path(folder)
    for node in group.nodes:
        if BAKE_FILE not in node:
            continue
        path = folder / f"{node[BAKE_FILE]}.exr"
        image = bpy.data.images.load(str(path), check_existing=True)
        image.colorspace_settings.name = "Non-Color"
        node.image = image
