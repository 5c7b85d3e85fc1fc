"""Build the Cook-Torrance node group from its description, node_groups/cook_torrance.toml.

The description is data: frames of named nodes written as nested calls (see the file's header).
This module parses each expression into Blender shader nodes, wires them, puts each frame's
nodes into a frame named after the term, and selects the view with the View input. The group's
sockets are the model's interface (core.model.GROUP_INPUTS). The baked split-sum files
(core/ibl_bake.py) are loaded as images by ``set_bake``. With Light Transport Scene = 1 and
the full view, the Emission output is the model as Cycles closures instead (the description's
[scene], ``_scene_transport``).
"""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

import bpy

from ..core.errors import UserError
from ..core.files import NODE_GROUPS_DIR
from ..core.ibl_bake import DFG_SIZE, LEVEL_COUNT
from ..core.model import GROUP_INPUTS, GROUP_OUTPUTS, LIGHT_SLOTS, SCENE_VIEWS, VIEWS

DESCRIPTION = NODE_GROUPS_DIR / "cook_torrance.toml"
TAG = "ctlab_node_group"
BAKE_FILE = "ctlab_bake_file"           # texture nodes: which baked file they read
BAKE_DIM = "ctlab_bake_dim"             # value nodes: that file's width or height


SOCKET_TYPES = {"FLOAT": "NodeSocketFloat", "INT": "NodeSocketInt", "RGBA": "NodeSocketColor",
                "VECTOR": "NodeSocketVector", "SHADER": "NodeSocketShader"}
VECTOR_VALUE_OPS = {"DOT_PRODUCT", "LENGTH", "DISTANCE"}
# Terms that the Emission output adds as closures which Cycles can skip (the file's header)
CLOSURE_OPS = ("gated", "prefiltered")
POLE_MARGIN = 3e-3      # radians: the least distance of a lat-long lookup from a pole


def load_description(path: Path = DESCRIPTION) -> dict:
    with open(path, "rb") as f:
        data = tomllib.load(f)
    if list(data["views"]) != list(VIEWS):
        raise UserError(f"{path}: the views must be, in order: {', '.join(VIEWS)}")
    if data["lights"]["slots"] != LIGHT_SLOTS:
        raise UserError(f"{path}: it is written for {data['lights']['slots']} light slots; the "
                        f"model has {LIGHT_SLOTS}")
    if not {"label", "on", "multi_ggx", "specular", "diffuse"} <= set(data.get("scene", {})):
        raise UserError(f"{path}: its [scene] table needs label, on, multi_ggx, specular.* "
                        "and diffuse.* (the scene transport's closures)")
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


# --- The lights: per-light frames and all_lights() (the description's [lights]) -----------
#
# The per-light frames are built once, into a group of their own ("<group> Light"), whose
# inputs are the light's fields and the quantities of the other frames those frames use, and
# whose outputs are the per-light nodes the rest of the description uses. The main group holds
# one instance of it for the key Sun and one for each slot (Cycles and EEVEE flatten groups
# when they compile, so this costs nothing when rendering; building 9 copies of the frames
# into one tree would take Blender seconds, since adding a node costs time in proportion to
# the nodes already in the tree).

LIGHT_GROUP = "ctlab_light_group"       # tags the per-light group


def _per_light_names(data: dict) -> set:
    return {name for spec in data["frames"].values() if spec.get("per_light")
            for name in spec["nodes"]}


def _refs(tree, found: set) -> set:
    if tree[0] == "ref":
        found.add(tree[1])
    elif tree[0] == "call":
        for a in tree[2]:
            _refs(a, found)
    return found


def _all_lights(tree, per_light: set, slots: int):
    """``all_lights(x)``, the sum of the per-light node x over the key Sun and every slot, as
    vec.ADD of the lights' instances (x, x_1, ...)."""
    if tree[0] != "call":
        return tree
    _, op, args = tree
    if op == "all_lights":
        if len(args) != 1 or args[0][0] != "ref" or args[0][1] not in per_light:
            raise UserError("node description: all_lights() takes the name of a per-light node")
        name = args[0][1]
        total = ("ref", name)
        for i in range(1, slots + 1):
            total = ("call", "vec.ADD", [total, ("ref", f"{name}_{i}")])
        return total
    return ("call", op, [_all_lights(a, per_light, slots) for a in args])


def _kind(tree, exprs: dict, inputs: dict) -> str:
    """FLOAT or VECTOR: what an expression gives (colours are vectors here). ``inputs``:
    group input name -> kind."""
    kind = tree[0]
    if kind == "num":
        return "FLOAT"
    if kind == "ref":
        name = tree[1]
        if name.startswith("in."):
            return inputs[name[3:]]
        if name.startswith("geo."):
            return "VECTOR"
        return _kind(exprs[name][1], exprs, inputs)
    _, op, args = tree
    if op.startswith("math.") or op in ("x", "y", "z", "pick"):
        return "FLOAT"
    if op.startswith("vec."):
        return "FLOAT" if op[4:] in VECTOR_VALUE_OPS else "VECTOR"
    if op == "gated":
        return _kind(args[1], exprs, inputs)
    return "VECTOR"


def _input_kinds() -> dict:
    return {i.group: ("FLOAT" if i.kind in ("FLOAT", "INT") else "VECTOR")
            for i in GROUP_INPUTS}


class LightPlan:
    """The description split for the per-light group: its inputs (the light's fields, then the
    other frames' quantities it uses), its node expressions and its outputs (the per-light
    nodes used elsewhere; a closure term's arguments as ``name.0``, ``name.1``...)."""

    def __init__(self, data: dict):
        self.slots = data["lights"]["slots"]
        self.key_sun = {field: parse(text) for field, text in data["lights"]["key"].items()}
        self.fields = list(self.key_sun)
        per_light = self.per_light = _per_light_names(data)
        main, sub = {}, {}
        for frame, spec in data["frames"].items():
            for name, text in spec["nodes"].items():
                tree = _all_lights(parse(text), per_light, self.slots)
                (sub if spec.get("per_light") else main)[name] = (frame, tree)
        self.views = {view: _all_lights(parse(text), per_light, self.slots)
                      for view, text in data["views"].items()}
        used_outside = set()
        for _, tree in list(main.values()) + [(None, t) for t in self.views.values()]:
            used_outside |= _refs(tree, set())
        globals_used = []
        self.exprs = {}                    # the per-light group's nodes
        for name, (frame, tree) in sub.items():
            for ref in _refs(tree, set()):
                if ref.startswith("light."):
                    if ref[6:] not in self.key_sun:
                        raise UserError(f"node description: the key Sun has no {ref[6:]!r}")
                elif ref in main and ref not in globals_used:
                    globals_used.append(ref)
            self.exprs[name] = (frame, self._localise(tree, main))
        kinds = _input_kinds()
        field_kinds = {f: kinds[f"Light 1 {f}"] for f in self.fields}
        self.globals = globals_used
        self.inputs = [(f, field_kinds[f]) for f in self.fields] + \
            [(g, _kind(main[g][1], main, kinds)) for g in globals_used]
        self.outputs = []
        self.closures = {}                 # per-light closure term -> (op, argument count)
        sub_kinds = dict(self.inputs)
        for name in sub:
            if name not in used_outside:
                continue
            frame, tree = self.exprs[name]
            if tree[0] == "call" and tree[1] in CLOSURE_OPS:
                self.closures[name] = (tree[1], len(tree[2]))
                for k, arg in enumerate(tree[2]):
                    self.exprs[f"{name}.{k}"] = (frame, arg)
                    self.outputs.append((f"{name}.{k}", _kind(arg, self.exprs, sub_kinds)))
            else:
                self.outputs.append((name, _kind(tree, self.exprs, sub_kinds)))
        self.main = main

    def _localise(self, tree, main):
        """A per-light expression inside the per-light group: the light's fields and the other
        frames' quantities become its inputs."""
        if tree[0] == "ref":
            name = tree[1]
            if name.startswith("light."):
                return ("ref", "in." + name[6:])
            return ("ref", "in." + name) if name in main else tree
        if tree[0] == "call":
            return ("call", tree[1], [self._localise(a, main) for a in tree[2]])
        return tree

    def main_exprs(self) -> dict:
        """The main group's nodes: its own, and each per-light output for each light as
        ("light", suffix, output) (a closure term as its op over such outputs)."""
        exprs = dict(self.main)
        for suffix in [""] + [f"_{i}" for i in range(1, self.slots + 1)]:
            for name, _kind_ in self.outputs:
                if "." not in name:
                    exprs[name + suffix] = ("lights", ("light", suffix, name))
            for name, (op, count) in self.closures.items():
                exprs[name + suffix] = ("lights", ("call", op, [
                    ("light", suffix, f"{name}.{k}") for k in range(count)]))
        return exprs


# --- Building ----------------------------------------------------------------------------

class _Builder:
    def __init__(self, tree: bpy.types.ShaderNodeTree, data: dict, exprs: dict,
                 lights: "LightPlan | None" = None, light_group=None):
        self.tree = tree
        self.nodes = tree.nodes
        self.data = data
        self.exprs = exprs                  # node name -> (frame, parsed expression)
        self.frame_labels = {key: spec["label"] for key, spec in data["frames"].items()}
        self.frame_labels["lights"] = ("The lights: the key Sun and each slot, each an "
                                       "instance of the per-light group")
        self.lights, self.light_group = lights, light_group
        self.light_nodes = {}               # suffix -> the per-light group's instance
        self.built = {}                     # (node name, mode or None) -> output socket
        self.frames = {}
        self.current_frame = None
        self.group_in = self.nodes.new("NodeGroupInput")
        self.geometry = None
        self.columns = {}
        self.horizontal = {}                # direction socket -> environment()'s parts
        # "colour": every term as a colour (the Value output); "emission": the closure terms
        # (CLOSURE_OPS) left out, for build_group to add as closures (the Emission output)
        self.mode = "colour"
        self.closure_terms = {}             # name -> (op, built arguments), in emission mode
        self.closure_names = []
        for name, (_, tree) in self.exprs.items():
            if tree[0] == "call" and tree[1] in CLOSURE_OPS:
                self.closure_names.append(name)
        self._depends = {}

    def depends(self, tree, names) -> bool:
        """Whether an expression refers, directly or not, to one of the named nodes."""
        if tree[0] == "call":
            return any(self.depends(a, names) for a in tree[2])
        if tree[0] == "ref" and tree[1] in self.exprs:
            key = (tree[1], tuple(names))
            if key not in self._depends:
                self._depends[key] = tree[1] in names or self.depends(self.exprs[tree[1]][1],
                                                                      names)
            return self._depends[key]
        return False

    def additive_count(self, tree, name):
        """How many times the closure term ``name`` enters an expression as a term of a sum
        (through vec.ADD alone), or None where it enters any other way."""
        if not self.depends(tree, [name]):
            return 0
        if tree[0] == "ref":
            return 1 if tree[1] == name else self.additive_count(self.exprs[tree[1]][1], name)
        if tree[1] != "vec.ADD":
            return None
        counts = [self.additive_count(a, name) for a in tree[2]]
        return None if None in counts else sum(counts)

    def frame(self, key):
        if key not in self.frames:
            f = self.nodes.new("NodeFrame")
            f.name = f"frame_{key}"
            f.label = self.frame_labels.get(key, key)
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
        if name not in self.exprs:
            raise UserError(f"node description: unknown name {name!r}")
        frame, tree = self.exprs[name]
        key = (name, self.mode if self.depends(("ref", name), self.closure_names) else None)
        if key in self.built:
            return self.built[key]
        if self.mode == "emission" and name in self.closure_names:
            # left out of the colour: build_group adds it as closures
            self.closure_terms[name] = (tree[1], [self.value(a) for a in tree[2]])
            self.built[key] = 0.0
            return 0.0
        saved, self.current_frame = self.current_frame, frame
        sock = self.value(tree)
        self.current_frame = saved
        if isinstance(sock, bpy.types.NodeSocket) and not sock.node.label:
            sock.node.label = name
        self.built[key] = sock
        return sock

    def value(self, tree):
        kind = tree[0]
        if kind == "num":
            return tree[1]
        if kind == "light":
            return self.light_node(tree[1]).outputs[tree[2]]
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
            return self.environment(args[0], args[1])
        if op == "table":
            return self.table(args[0], args[1], args[2])
        if op == "gated":
            return args[1]
        if op == "prefiltered":
            x, direction, factor = args
            total = None
            for k in range(LEVEL_COUNT):
                # hat weight max(0, 1 - |x - k|): the two neighbouring levels, blended linearly
                w = self.call("math.MAXIMUM", [self.call("math.SUBTRACT", [
                    1.0, self.call("math.ABSOLUTE", [self.call("math.SUBTRACT", [x, float(k)])])]),
                    0.0])
                term = self.call("vec.SCALE", [self.environment(f"specular_{k}", direction), w])
                total = term if total is None else self.call("vec.ADD", [total, term])
            return self.call("vec.MULTIPLY", [total, factor])
        raise UserError(f"node description: unknown operation {op!r}")

    def light_node(self, suffix: str):
        """The per-light group's instance for the key Sun ("") or slot i ("_i"), its inputs
        fed from the key Sun's expressions or the slot's group inputs, and this group's
        quantities."""
        if suffix not in self.light_nodes:
            saved, self.current_frame = self.current_frame, "lights"
            node = self.new("ShaderNodeGroup")
            node.node_tree = self.light_group
            node.label = f"Light {suffix[1:]}" if suffix else "Key Sun"
            node.width = 180
            self.light_nodes[suffix] = node
            for name in self.lights.fields:
                source = self.lights.key_sun[name] if not suffix else \
                    ("ref", f"in.Light {suffix[1:]} {name}")
                self.link(self.value(source), node.inputs[name])
            for name in self.lights.globals:
                self.link(self.socket(name), node.inputs[name])
            self.current_frame = saved
        return self.light_nodes[suffix]

    def dimension(self, key, dim):
        """A Value node that set_bake sets to a baked file's width or height."""
        value = self.new("ShaderNodeValue")
        value.label = f"{key} {dim}"
        value[BAKE_FILE] = key
        value[BAKE_DIM] = dim
        value.outputs[0].default_value = 1.0
        return value.outputs[0]

    def environment(self, key, d):
        """A baked lat-long file toward d: an Environment Texture node, Linear (bilinear at
        texel centres, no mip-maps in Cycles or EEVEE; Blender's equirectangular mapping, s
        periodic). The model clamps t to the centres of the first and last rows; Cycles
        wraps it (REPEAT), mixing the two poles. So d's elevation is limited here to
        pi/2 - delta: its horizontal part h is scaled by k = max(1, |d.z| tan(delta) / h), and
        a direction exactly at a pole (h = 0, a flat floor's normal) is given the horizontal
        part |d.z| tan(delta) along +x, where the model's s is 0.5 as well.

        delta is half a row, pi/(2H), but at least POLE_MARGIN: Cycles finds t from
        acos(d.z / |d|) in float32, which cannot resolve half a row of a tall image (at
        H = 1024 it overshot the last row's centre by 1% of a row, at H = 4096 by half a
        row). For H > 524 the lookup reads a little below the last row's centre instead."""
        if d not in self.horizontal:
            dx, dy, dz = (self.call(c, [d]) for c in ("x", "y", "z"))
            h = self.call("math.SQRT", [self.call("math.ADD", [
                self.call("math.MULTIPLY", [dx, dx]), self.call("math.MULTIPLY", [dy, dy])])])
            at_pole = self.call("math.LESS_THAN", [h, 1e-20])
            self.horizontal[d] = (self.call("math.ABSOLUTE", [dz]),
                                  self.call("math.MAXIMUM", [h, 1e-20]),
                                  at_pole, self.call("math.SUBTRACT", [1.0, at_pole]))
        abs_z, h, at_pole, off_pole = self.horizontal[d]
        delta = self.call("math.MAXIMUM", [self.call("math.DIVIDE", [
            1.5707963267948966, self.dimension(key, "height")]), POLE_MARGIN])
        least = self.call("math.MULTIPLY", [abs_z, self.call("math.TANGENT", [delta])])
        k = self.call("math.MULTIPLY", [self.call("math.MAXIMUM", [
            1.0, self.call("math.DIVIDE", [least, h])]), off_pole])
        clamped = self.call("vec.ADD", [
            self.call("vec.MULTIPLY", [d, self.call("vec3", [k, k, 1.0])]),
            self.call("vec3", [self.call("math.MULTIPLY", [least, at_pole]), 0.0, 0.0])])
        return self.lookup(key, clamped)

    def lookup(self, key, d):
        node = self.new("ShaderNodeTexEnvironment", interpolation='Linear',
                        projection='EQUIRECTANGULAR')
        node.label = key
        node[BAKE_FILE] = key
        self.link(d, node.inputs["Vector"])
        return node.outputs["Color"]

    def table(self, key, u, v):
        """A baked table at (u, v), bilinear, for (u, v) within the texel centres' range.
        Read by an Environment Texture node toward the direction that Blender's
        equirectangular mapping takes to (u, v), phi = 2 pi (0.5 - u), theta = pi (v - 0.5):
        one bilinear lookup without mip-maps in both Cycles and EEVEE (an Image Texture
        node's Linear lookups use mip-maps in EEVEE). The round trip through the angles costs
        up to 4e-5 of a texel in float32; (u, v) stays half a texel inside the edges, so the
        wrapped neighbour's weight is at most about 4e-6."""
        phi = self.call("math.MULTIPLY", [self.call("math.SUBTRACT", [0.5, u]),
                                          6.283185307179586])
        theta = self.call("math.MULTIPLY", [self.call("math.SUBTRACT", [v, 0.5]),
                                            3.141592653589793])
        cos_theta = self.call("math.COSINE", [theta])
        return self.lookup(key, self.call("vec3", [
            self.call("math.MULTIPLY", [cos_theta, self.call("math.COSINE", [phi])]),
            self.call("math.MULTIPLY", [cos_theta, self.call("math.SINE", [phi])]),
            self.call("math.SINE", [theta])]))


def _interface(group):
    """The group's sockets: the model's interface (core.model), in its order."""
    panel = None
    for i in GROUP_INPUTS:
        if i.key.startswith("light") and panel is None:
            # the light slots, in a panel the artist opens when needed (drivers fill them)
            panel = group.interface.new_panel("Lights", default_closed=True)
        sock = group.interface.new_socket(i.group, in_out='INPUT',
                                          socket_type=SOCKET_TYPES[i.kind], parent=panel)
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


def _tree(name: str, tag: str) -> bpy.types.ShaderNodeTree:
    """The shader node tree of that name made by this add-on, emptied, or a new one."""
    group = bpy.data.node_groups.get(name)
    if group is None or group.bl_idname != "ShaderNodeTree":
        group = bpy.data.node_groups.new(name, "ShaderNodeTree")
    group[tag] = True
    group.nodes.clear()
    group.interface.clear()
    return group


def build_light_group(data: dict, plan: LightPlan, name: str) -> bpy.types.ShaderNodeTree:
    """The per-light group: the per_light frames once, over the plan's inputs and outputs."""
    group = _tree(name, LIGHT_GROUP)
    group.description = "One light of the Cook-Torrance Lab group (node_groups/cook_torrance.toml)"
    for label, kind in plan.inputs:
        group.interface.new_socket(label, in_out='INPUT', socket_type=SOCKET_TYPES[kind])
    for label, kind in plan.outputs:
        group.interface.new_socket(label, in_out='OUTPUT', socket_type=SOCKET_TYPES[kind])
    b = _Builder(group, data, plan.exprs)
    b.group_in.location = (-600, 0)
    out = group.nodes.new("NodeGroupOutput")
    out.location = (2800, 0)
    for label, _ in plan.outputs:
        b.link(b.socket(label), out.inputs[label])
    return group


def build_group(name: str | None = None) -> bpy.types.ShaderNodeTree:
    """The node group, built anew from node_groups/cook_torrance.toml (an existing group of
    the same name made by this add-on is rebuilt in place, so materials keep using it), with
    its per-light group ("<name> Light")."""
    data = load_description()
    name = name or data["group"]["name"]
    plan = LightPlan(data)
    light_group = build_light_group(data, plan, f"{name} Light")
    group = _tree(name, TAG)
    group.description = data["group"]["description"]
    _interface(group)
    b = _Builder(group, data, plan.main_exprs(), plan, light_group)
    b.group_in.location = (-600, 0)
    b.current_frame = "views"
    b.frames["views"] = b.frame("views")
    b.frames["views"].label = "View (term isolation) and the output"
    views = plan.views
    view_on = [b.call("math.COMPARE", [b.socket("in.View"), float(k), 0.5])
               for k in range(len(views))]

    def select(mode):
        """The chosen view: the sum over k of (View == k) x view_k."""
        b.mode = mode
        total = None
        for on, tree in zip(view_on, views.values()):
            term = b.call("vec.SCALE", [b.value(tree), on])
            b.current_frame = "views"
            total = term if total is None else b.call("vec.ADD", [total, term])
        return total

    colour = select("colour")
    emission = _closures(b, views, view_on, select("emission"))
    emission = _scene_transport(b, data["scene"], view_on, emission)
    out = group.nodes.new("NodeGroupOutput")
    out.location = (2800, 0)
    group.links.new(emission, out.inputs["Emission"])
    group.links.new(colour, out.inputs["Value"])
    return group


def _closures(b: _Builder, views: dict, view_on: list, rest):
    """The Emission output: the view's colour without its closure terms, plus each term as
    an Emission closure behind Mix Shader nodes, whose zero-weight branches Cycles skips with
    every node that only they use. The views are sums of terms, so a term enters each view
    that uses it once, with weight (View == k).

    - ``gated(c, X)``: mix(nothing, X, c > 0), for a term that is zero where c <= 0 (the
      direct light where n.l <= 0).
    - ``prefiltered(x, dir, c)``: sum_k max(0, 1 - |x - k|) L_k(dir) c as a chain,
      M_6 = L_6 c, M_k = mix(L_k c, M_k+1, clamp(x - k, 0, 1)). For x in [j, j + 1] this is
      (1 - f) L_j c + f L_j+1 c, the same sum, and Cycles reads two levels, not seven."""
    b.current_frame = "views"

    def emit(colour):
        node = b.new("ShaderNodeEmission")
        b.link(colour, node.inputs["Color"])
        node.inputs["Strength"].default_value = 1.0
        return node.outputs["Emission"]

    def mix(fac, first, second, label):
        node = b.new("ShaderNodeMixShader")
        node.label = label
        b.link(fac, node.inputs["Fac"])
        if first is not None:
            b.link(first, node.inputs[1])
        b.link(second, node.inputs[2])
        return node.outputs["Shader"]

    total = emit(rest)
    for name, (op, args) in b.closure_terms.items():
        weight = None
        for on, (view, tree) in zip(view_on, views.items()):
            count = b.additive_count(tree, name)
            if count not in (0, 1):
                raise UserError(f"node description: the view {view!r} must hold {name!r} at "
                                "most once, as a term of a sum (vec.ADD), since the group's "
                                "Emission output adds it as a closure")
            if count:
                weight = on if weight is None else b.call("math.ADD", [weight, on])
        if op == "gated":
            c, colour = args
            closure = mix(b.call("math.GREATER_THAN", [c, 0.0]), None,
                          emit(b.call("vec.SCALE", [colour, weight])), name)
        else:
            x, direction, factor = args
            factor = b.call("vec.SCALE", [factor, weight])

            def level(k):
                return emit(b.call("vec.MULTIPLY", [
                    b.environment(f"specular_{k}", direction), factor]))
            closure = level(LEVEL_COUNT - 1)
            for k in range(LEVEL_COUNT - 2, -1, -1):
                closure = mix(b.call("math.SUBTRACT!", [x, float(k)]), level(k), closure,
                              f"{name}: levels {k}-{LEVEL_COUNT - 1}")
        add = b.new("ShaderNodeAddShader")
        b.link(total, add.inputs[0])
        b.link(closure, add.inputs[1])
        total = add.outputs["Shader"]
    return total


def _scene_transport(b: _Builder, spec: dict, view_on: list, lab):
    """The Emission output with the scene transport (the description's [scene]): where
    Light Transport Scene is 1 and the View is one of SCENE_VIEWS (full), the model as
    closures that Cycles path traces, else ``lab`` (the lab's emission). A Mix Shader of
    factor exactly 0 or 1 selects, so Cycles skips the other side with every node that only
    it uses.

    The closures, as the OSL shader's scene_closures():
    - a Metallic BSDF, Fresnel F82 with a white Edge Tint: Cycles' F82-tint Fresnel is
      Schlick's F(mu) = F0 + (1 - F0)(1 - mu)^5 minus b mu (1 - mu)^6, with b proportional to
      (1 - tint), so 0 here: Schlick's F on Base Color = specColor. GGX D and the
      height-correlated Smith G, single scattering; Multiscatter GGX where ``multi_ggx`` is 1
      (Energy Compensated: Cycles' albedo scaling with Kulla and Conty's Fresnel term, the
      model's k_ms for its own tables: an approximation, exact only up to Cycles' E table).
      The node squares its Roughness, so Roughness = sqrt(alpha) = max(pr, sqrt(0.002)).
    - plus a Diffuse BSDF of Roughness 0: Lambert's diffColor / pi.
    Both on the shading normal n.

    This is the model exactly for G = smith_ggx_correlated, Lambert's diffuse and no energy
    compensation. For Cook-Torrance's and Unity's G, Disney's diffuse (SVM has no Burley
    closure) and the compensated lobe the closures approximate the model; the node group has
    no correction emission (the OSL shader adds one)."""
    frame = b.current_frame = "scene"
    b.frame_labels[frame] = spec["label"]
    b.mode = "colour"

    def value(text):
        sock = b.value(parse(text))
        b.current_frame = frame
        return sock

    def specular(distribution):
        node = b.new("ShaderNodeBsdfMetallic", distribution=distribution, fresnel_type='F82')
        node.label = f"specular ({distribution})"
        b.link(colour, node.inputs["Base Color"])
        node.inputs["Edge Tint"].default_value = (1.0, 1.0, 1.0, 1.0)
        b.link(roughness, node.inputs["Roughness"])
        b.link(normal, node.inputs["Normal"])
        return node.outputs["BSDF"]

    def mix(fac, first, second, label):
        node = b.new("ShaderNodeMixShader")
        node.label = label
        b.link(fac, node.inputs["Fac"])
        b.link(first, node.inputs[1])
        b.link(second, node.inputs[2])
        return node.outputs["Shader"]

    on = value(spec["on"])
    weight = None
    for view in SCENE_VIEWS:
        k = VIEWS.index(view)
        weight = view_on[k] if weight is None else b.call("math.ADD", [weight, view_on[k]])
    scene_on = b.call("math.MULTIPLY", [on, weight])
    scene_on.node.label = "scene transport on"

    colour, roughness, normal = (value(spec["specular"][k])
                                 for k in ("color", "roughness", "normal"))
    if not roughness.node.label:
        roughness.node.label = "roughness = sqrt(alpha)"
    single, multiple = specular('GGX'), specular('MULTI_GGX')
    spec_closure = mix(value(spec["multi_ggx"]), single, multiple, "specular: multiple scattering")
    diffuse = b.new("ShaderNodeBsdfDiffuse")
    diffuse.label = "diffuse (Lambert)"
    b.link(value(spec["diffuse"]["color"]), diffuse.inputs["Color"])
    diffuse.inputs["Roughness"].default_value = 0.0
    b.link(value(spec["diffuse"]["normal"]), diffuse.inputs["Normal"])
    add = b.new("ShaderNodeAddShader")
    add.label = "scene closures"
    b.link(spec_closure, add.inputs[0])
    b.link(diffuse.outputs["BSDF"], add.inputs[1])
    return mix(scene_on, lab, add.outputs["Shader"], "lab emission or scene closures")


SOURCE_HASH = "ctlab_source_hash"


def ensure_group() -> bpy.types.ShaderNodeTree:
    """The node group, reused when it was built from the current description (rebuilding
    would reset the inputs and links of every material using it), else built."""
    import hashlib
    digest = hashlib.sha256(DESCRIPTION.read_bytes() + repr(GROUP_INPUTS).encode()
                            + Path(__file__).read_bytes()).hexdigest()[:16]
    group = bpy.data.node_groups.get(load_description()["group"]["name"])
    if group is not None and group.get(TAG) and group.get(SOURCE_HASH) == digest:
        return group
    group = build_group()
    group[SOURCE_HASH] = digest
    return group


def set_bake(group: bpy.types.ShaderNodeTree, folder) -> None:
    """Point the group's texture nodes at a bake folder's files (addon/ibl_bake.py)."""
    folder = Path(folder)
    trees = [group] + list({n.node_tree for n in group.nodes          # and the per-light group
                            if n.bl_idname == "ShaderNodeGroup" and n.node_tree is not None
                            and n.node_tree.get(LIGHT_GROUP)})
    for node in (node for tree in trees for node in tree.nodes):
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
