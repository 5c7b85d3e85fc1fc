"""Build the Cook-Torrance node group from its description, node_groups/cook_torrance.toml.

The description is data: frames of named nodes written as nested calls (see the file's header),
read, checked, parsed and planned without Blender by core/node_description.py. This module
turns each parsed expression into Blender shader nodes, wires them, puts each frame's
nodes into a frame named after the term, and selects the view with the View input. The group's
sockets are the model's interface (core.model.GROUP_INPUTS). The baked split-sum files
(core/ibl_bake.py) are loaded as images by ``set_bake``, with the scene transport's tables
(core/correction_tables.py). With Light Transport Scene = 1
and the full view, the Emission output is the model as Cycles closures instead, plus the
correction emission (the description's [scene], ``_scene_transport``).
"""

from __future__ import annotations

from pathlib import Path

import bpy

from ..core.correction_tables import CORRECTION_TABLES, correction_table_folder
from ..core.errors import UserError
from ..core.ibl_bake import LEVEL_COUNT
from ..core.model import GROUP_INPUTS, GROUP_OUTPUTS, SCENE_VIEWS, VIEWS
from ..core.node_description import (
    CLOSURE_OPS,
    CORRECTION_OUTPUTS,
    DESCRIPTION,
    VECTOR_VALUE_OPS,
    LightPlan,
    SubgroupPlan,
    load_description,
    parse,
)

TAG = "ctlab_node_group"
LIGHT_GROUP = "ctlab_light_group"  # tags the per-light group
CORRECTION_GROUP = "ctlab_correction_group"  # tags the correction group
BAKE_FILE = "ctlab_bake_file"  # texture nodes: which baked file they read
BAKE_DIM = "ctlab_bake_dim"  # value nodes: that file's width or height
MODEL_TABLE = "ctlab_model_table"  # texture nodes: which correction table they read
# The group's output of the residual albedo (core.model OSL_RESIDUAL), built where the
# interface (core.model GROUP_OUTPUTS) has it
RESIDUAL_OUTPUT = "Residual Albedo"


SOCKET_TYPES = {
    "FLOAT": "NodeSocketFloat",
    "INT": "NodeSocketInt",
    "RGBA": "NodeSocketColor",
    "VECTOR": "NodeSocketVector",
    "SHADER": "NodeSocketShader",
}
POLE_MARGIN = 3e-3  # radians: the least distance of a lat-long lookup from a pole


# --- Building ----------------------------------------------------------------------------


class _Builder:
    def __init__(
        self,
        tree: bpy.types.ShaderNodeTree,
        data: dict,
        exprs: dict,
        lights: LightPlan | None = None,
        light_group=None,
    ):
        self.tree = tree
        self.nodes = tree.nodes
        self.data = data
        self.exprs = exprs  # node name -> (frame, parsed expression)
        self.frame_labels = {key: spec["label"] for key, spec in data["frames"].items()}
        self.frame_labels["lights"] = (
            "The lights: the key Sun and each slot, each an instance of the per-light group"
        )
        self.lights, self.light_group = lights, light_group
        self.light_nodes = {}  # suffix -> the per-light group's instance
        self.built = {}  # (node name, mode or None) -> output socket
        self.frames = {}
        self.current_frame = None
        self.group_in = self.nodes.new("NodeGroupInput")
        self.geometry = None
        self.columns = {}
        self.horizontal = {}  # direction socket -> environment()'s parts
        self.table_directions = {}  # (u, v) sockets -> table()'s direction
        # "colour": every term as a colour (the Value output); "emission": the closure terms
        # (CLOSURE_OPS) left out, for build_group to add as closures (the Emission output)
        self.mode = "colour"
        self.closure_terms = {}  # name -> (op, built arguments), in emission mode
        self.chain_group = None  # prefiltered() as instances of this group
        self.closure_names = []
        for name, (_, tree) in self.exprs.items():
            if tree[0] == "call" and tree[1] in CLOSURE_OPS:
                self.closure_names.append(name)
        self._depends = {}

    def emission(self, colour):
        """An Emission closure of ``colour`` at strength 1."""
        node = self.new("ShaderNodeEmission")
        self.link(colour, node.inputs["Color"])
        node.inputs["Strength"].default_value = 1.0
        return node.outputs["Emission"]

    def mix_shader(self, fac, first, second, label):
        """A Mix Shader of ``first`` (None: no closure) and ``second`` by ``fac``."""
        node = self.new("ShaderNodeMixShader")
        node.label = label
        self.link(fac, node.inputs["Fac"])
        if first is not None:
            self.link(first, node.inputs[1])
        self.link(second, node.inputs[2])
        return node.outputs["Shader"]

    def depends(self, tree, names) -> bool:
        """Whether an expression refers, directly or not, to one of the named nodes."""
        if tree[0] == "call":
            return any(self.depends(a, names) for a in tree[2])
        if tree[0] == "ref" and tree[1] in self.exprs:
            key = (tree[1], tuple(names))
            if key not in self._depends:
                self._depends[key] = tree[1] in names or self.depends(self.exprs[tree[1]][1], names)
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
        if op in ("env", "table"):  # the first argument names a baked file
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
                return self.call(
                    "math.ADD",
                    [self.call("math.MULTIPLY", [a, not_c]), self.call("math.MULTIPLY", [b, c])],
                )
            return self.call(
                "vec.ADD", [self.call("vec.SCALE", [a, not_c]), self.call("vec.SCALE", [b, c])]
            )
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
                w = self.call(
                    "math.MAXIMUM",
                    [
                        self.call(
                            "math.SUBTRACT",
                            [
                                1.0,
                                self.call(
                                    "math.ABSOLUTE", [self.call("math.SUBTRACT", [x, float(k)])]
                                ),
                            ],
                        ),
                        0.0,
                    ],
                )
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
                source = (
                    self.lights.key_sun[name]
                    if not suffix
                    else ("ref", f"in.Light {suffix[1:]} {name}")
                )
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
            h = self.call(
                "math.SQRT",
                [
                    self.call(
                        "math.ADD",
                        [
                            self.call("math.MULTIPLY", [dx, dx]),
                            self.call("math.MULTIPLY", [dy, dy]),
                        ],
                    )
                ],
            )
            at_pole = self.call("math.LESS_THAN", [h, 1e-20])
            self.horizontal[d] = (
                self.call("math.ABSOLUTE", [dz]),
                self.call("math.MAXIMUM", [h, 1e-20]),
                at_pole,
                self.call("math.SUBTRACT", [1.0, at_pole]),
            )
        abs_z, h, at_pole, off_pole = self.horizontal[d]
        delta = self.call(
            "math.MAXIMUM",
            [
                self.call("math.DIVIDE", [1.5707963267948966, self.dimension(key, "height")]),
                POLE_MARGIN,
            ],
        )
        least = self.call("math.MULTIPLY", [abs_z, self.call("math.TANGENT", [delta])])
        k = self.call(
            "math.MULTIPLY",
            [self.call("math.MAXIMUM", [1.0, self.call("math.DIVIDE", [least, h])]), off_pole],
        )
        clamped = self.call(
            "vec.ADD",
            [
                self.call("vec.MULTIPLY", [d, self.call("vec3", [k, k, 1.0])]),
                self.call("vec3", [self.call("math.MULTIPLY", [least, at_pole]), 0.0, 0.0]),
            ],
        )
        return self.lookup(key, clamped)

    def lookup(self, key, d):
        node = self.new(
            "ShaderNodeTexEnvironment", interpolation='Linear', projection='EQUIRECTANGULAR'
        )
        node.label = key
        node[MODEL_TABLE if key in CORRECTION_TABLES else BAKE_FILE] = key
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
        if (u, v) not in self.table_directions:  # one direction for the tables at (u, v)
            phi = self.call(
                "math.MULTIPLY", [self.call("math.SUBTRACT", [0.5, u]), 6.283185307179586]
            )
            theta = self.call(
                "math.MULTIPLY", [self.call("math.SUBTRACT", [v, 0.5]), 3.141592653589793]
            )
            cos_theta = self.call("math.COSINE", [theta])
            self.table_directions[u, v] = self.call(
                "vec3",
                [
                    self.call("math.MULTIPLY", [cos_theta, self.call("math.COSINE", [phi])]),
                    self.call("math.MULTIPLY", [cos_theta, self.call("math.SINE", [phi])]),
                    self.call("math.SINE", [theta]),
                ],
            )
        return self.lookup(key, self.table_directions[u, v])


def _interface(group):
    """The group's sockets: the model's interface (core.model), in its order."""
    panel = None
    for i in GROUP_INPUTS:
        if i.key.startswith("light") and panel is None:
            # the light slots, in a panel the artist opens when needed (drivers fill them)
            panel = group.interface.new_panel("Lights", default_closed=True)
        sock = group.interface.new_socket(
            i.group, in_out='INPUT', socket_type=SOCKET_TYPES[i.kind], parent=panel
        )
        sock.description = i.tooltip
        if i.kind in ("FLOAT", "INT"):
            cast = int if i.kind == "INT" else float
            sock.default_value, sock.min_value, sock.max_value = (
                cast(i.default),
                cast(i.min),
                cast(i.max),
            )
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


def build_correction_group(
    data: dict, plan: SubgroupPlan, name: str, chain_group
) -> bpy.types.ShaderNodeTree:
    """The correction group: the frames marked correction_group once, over the plan's
    inputs; its outputs the world's correction (a shader, its closure terms as
    ``_closures`` builds them) and the residual albedo (a colour)."""
    group = _tree(name, CORRECTION_GROUP)
    group.description = (
        "The scene transport's correction for the world and its residual "
        "albedo (Cook-Torrance Lab; node_groups/cook_torrance.toml)"
    )
    for label, kind, _ in plan.inputs:
        group.interface.new_socket(label, in_out='INPUT', socket_type=SOCKET_TYPES[kind])
    for label, kind in CORRECTION_OUTPUTS.values():
        group.interface.new_socket(label, in_out='OUTPUT', socket_type=SOCKET_TYPES[kind])
    b = _Builder(group, data, plan.exprs)
    b.chain_group = chain_group
    b.group_in.location = (-600, 0)
    b.current_frame = frame = "correction"
    b.mode = "emission"
    rest = b.value(plan.roots["correction_world"])
    world = _closures(b, {"correction_world": plan.roots["correction_world"]}, None, rest, frame)
    b.mode = "colour"
    residual = b.value(plan.roots["residual"])
    out = group.nodes.new("NodeGroupOutput")
    out.location = (2800, 0)
    group.links.new(world, out.inputs[CORRECTION_OUTPUTS["correction_world"][0]])
    b.link(residual, out.inputs[CORRECTION_OUTPUTS["residual"][0]])
    return group


def build_group(name: str | None = None) -> bpy.types.ShaderNodeTree:
    """The node group, built anew from node_groups/cook_torrance.toml (an existing group of
    the same name made by this add-on is rebuilt in place, so materials keep using it), with
    its per-light group ("<name> Light") and its correction group ("<name> Correction")."""
    data = load_description()
    name = name or data["group"]["name"]
    plan = LightPlan(data)
    light_group = build_light_group(data, plan, f"{name} Light")
    correction_group = build_correction_group(
        data, plan.correction, f"{name} Correction", build_chain_group(data, f"{name} Pre-filtered")
    )
    group = _tree(name, TAG)
    group.description = data["group"]["description"]
    _interface(group)
    b = _Builder(group, data, plan.main_exprs(), plan, light_group)
    b.group_in.location = (-600, 0)
    b.current_frame = "views"
    b.frames["views"] = b.frame("views")
    b.frames["views"].label = "View (term isolation) and the output"
    views = plan.views
    view_on = [
        b.call("math.COMPARE", [b.socket("in.View"), float(k), 0.5]) for k in range(len(views))
    ]

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
    emission, residual = _scene_transport(b, data["scene"], view_on, emission, correction_group)
    out = group.nodes.new("NodeGroupOutput")
    out.location = (2800, 0)
    group.links.new(emission, out.inputs["Emission"])
    group.links.new(colour, out.inputs["Value"])
    if RESIDUAL_OUTPUT in out.inputs:
        group.links.new(residual, out.inputs[RESIDUAL_OUTPUT])
    return group


def _closures(b: _Builder, views: dict, view_on: list, rest, frame: str = "views"):
    """The Emission output: the view's colour without its closure terms, plus each term as
    an Emission closure behind Mix Shader nodes, whose zero-weight branches Cycles skips with
    every node that only they use. The views are sums of terms, so a term enters each view
    that uses it once, with weight (View == k) (``view_on``; None: weight 1, for a sum that
    is not chosen by the View, the scene transport's correction).

    - ``gated(c, X)``: mix(nothing, X, c > 0), for a term that is zero where c <= 0 (the
      direct light where n.l <= 0).
    - ``prefiltered(x, dir, c)``: sum_k max(0, 1 - |x - k|) L_k(dir) c as a chain,
      M_6 = L_6 c, M_k = mix(L_k c, M_k+1, clamp(x - k, 0, 1)). For x in [j, j + 1] this is
      (1 - f) L_j c + f L_j+1 c, the same sum, and Cycles reads two levels, not seven.

    The closure terms are those the last emission-mode pass met (b.closure_terms), which
    this consumes."""
    b.current_frame = frame

    emit, mix = b.emission, b.mix_shader

    def weighted(colour, weight):
        return colour if weight is None else b.call("vec.SCALE", [colour, weight])

    total = emit(rest)
    terms, b.closure_terms = b.closure_terms, {}
    for name, (op, args) in terms.items():
        weight = None
        for k, (view, tree) in enumerate(views.items()):
            count = b.additive_count(tree, name)
            if count not in (0, 1):
                raise UserError(
                    f"node description: the view {view!r} must hold {name!r} at "
                    "most once, as a term of a sum (vec.ADD), since the group's "
                    "Emission output adds it as a closure"
                )
            if count and view_on is not None:
                on = view_on[k]
                weight = on if weight is None else b.call("math.ADD", [weight, on])
        if op == "gated":
            c, colour = args
            closure = mix(
                b.call("math.GREATER_THAN", [c, 0.0]), None, emit(weighted(colour, weight)), name
            )
        elif b.chain_group is not None:  # the chain below, as an instance of that group
            x, direction, factor = args
            node = b.new("ShaderNodeGroup")
            node.node_tree = b.chain_group
            node.label = name
            for sock, value in zip(CHAIN_INPUTS, (x, direction, weighted(factor, weight))):
                b.link(value, node.inputs[sock[0]])
            closure = node.outputs[0]
        else:
            x, direction, factor = args
            closure = _chain(b, x, direction, weighted(factor, weight), name, emit, mix)
        add = b.new("ShaderNodeAddShader")
        b.link(total, add.inputs[0])
        b.link(closure, add.inputs[1])
        total = add.outputs["Shader"]
    return total


def _chain(b: _Builder, x, direction, factor, name: str, emit, mix):
    """prefiltered(x, direction, factor) as a chain of Mix Shader nodes (``_closures``)."""

    def level(k):
        return emit(b.call("vec.MULTIPLY", [b.environment(f"specular_{k}", direction), factor]))

    closure = level(LEVEL_COUNT - 1)
    for k in range(LEVEL_COUNT - 2, -1, -1):
        closure = mix(
            b.call("math.SUBTRACT!", [x, float(k)]),
            level(k),
            closure,
            f"{name}: levels {k}-{LEVEL_COUNT - 1}",
        )
    return closure


# The correction group's pre-filtered terms are instances of one group of the chain (its
# many lookups built once)
CHAIN_INPUTS = (("Level", "FLOAT"), ("Direction", "VECTOR"), ("Colour", "VECTOR"))


def build_chain_group(data: dict, name: str) -> bpy.types.ShaderNodeTree:
    """prefiltered(Level, Direction, Colour) as Emission closures behind Mix Shader nodes,
    a group of its own (tagged as the correction group, so that set_bake finds its
    lookups)."""
    group = _tree(name, CORRECTION_GROUP)
    group.description = (
        "The pre-filtered levels toward a direction at a fractional level, "
        "times a colour, as Emission closures (Cook-Torrance Lab)"
    )
    for label, kind in CHAIN_INPUTS:
        group.interface.new_socket(label, in_out='INPUT', socket_type=SOCKET_TYPES[kind])
    group.interface.new_socket("Emission", in_out='OUTPUT', socket_type=SOCKET_TYPES["SHADER"])
    b = _Builder(group, data, {})
    b.group_in.location = (-600, 0)
    b.current_frame = "chain"
    b.frame_labels["chain"] = (
        "sum_k max(0, 1 - |Level - k|) L_k(Direction) Colour: a chain "
        "of Mix Shader nodes over the levels (two are read)"
    )

    emit, mix = b.emission, b.mix_shader

    sockets = [b.socket("in." + label) for label, _ in CHAIN_INPUTS]
    out = group.nodes.new("NodeGroupOutput")
    out.location = (2800, 0)
    group.links.new(_chain(b, *sockets, "prefiltered", emit, mix), out.inputs["Emission"])
    return group


def _scene_transport(b: _Builder, spec: dict, view_on: list, lab, correction_group):
    """The Emission output with the scene transport (the description's [scene]), and the
    residual albedo. Where Light Transport Scene is 1 and the View is one of SCENE_VIEWS
    (full), the model as closures that Cycles path traces plus the correction emission,
    else ``lab`` (the lab's emission). A Mix Shader of factor exactly 0 or 1 selects, so
    Cycles skips the other side with every node that only it uses (and, the switches being
    constants in a material, folds it away).

    The closures, as the OSL shader's scene_closures():
    - a Metallic BSDF, Fresnel F82 with a white Edge Tint: Cycles' F82-tint Fresnel is
      Schlick's F(mu) = F0 + (1 - F0)(1 - mu)^5 minus b mu (1 - mu)^6, with b proportional to
      (1 - tint), so 0 here: Schlick's F on Base Color = specColor. GGX D and the
      height-correlated Smith G, single scattering; Multiscatter GGX where ``multi_ggx`` is 1
      (Energy Compensated: Cycles' albedo scaling with Kulla and Conty's Fresnel term, the
      model's k_ms for Smith's tables, up to Cycles' own E table).
      The node squares its Roughness, so Roughness = sqrt(alpha) = max(pr, sqrt(0.002)).
    - plus a Diffuse BSDF of Roughness 0: Lambert's diffColor / pi.
    Both on the shading normal n.

    The correction (``correction``, an emission, signed): the group's own lab estimate of
    integral (f_model - f_closure) L (n.l) for the lights and the world, f_closure the
    closures' model (Smith's G, Lambert, and with energy compensated Smith's k_ms): term by
    term for each light (exact for the node group's unshadowed lights at their centres), the
    split-sum for the world. It sits behind a Mix Shader of factor ``correct``, 0 where the
    switches are the closures' own (Smith's G and Lambert, either energy), where the closures
    alone are the model. Its terms gated() and prefiltered() become closures as in the lab's
    emission (``_closures``), so Cycles skips a light's term where n.l <= 0 and reads two
    pre-filtered levels.

    The residual (``residual``), a colour: 0 but where the scene transport is on."""
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
        if first is not None:
            b.link(first, node.inputs[1])
        b.link(second, node.inputs[2])
        return node.outputs["Shader"]

    def add(first, second, label):
        node = b.new("ShaderNodeAddShader")
        node.label = label
        b.link(first, node.inputs[0])
        b.link(second, node.inputs[1])
        return node.outputs["Shader"]

    on = value(spec["on"])
    weight = None
    for view in SCENE_VIEWS:
        k = VIEWS.index(view)
        weight = view_on[k] if weight is None else b.call("math.ADD", [weight, view_on[k]])
    scene_on = b.call("math.MULTIPLY", [on, weight])
    scene_on.node.label = "scene transport on"

    colour, roughness, normal = (
        value(spec["specular"][k]) for k in ("color", "roughness", "normal")
    )
    if not roughness.node.label:
        roughness.node.label = "roughness = sqrt(alpha)"
    single, multiple = specular('GGX'), specular('MULTI_GGX')
    spec_closure = mix(value(spec["multi_ggx"]), single, multiple, "specular: multiple scattering")
    diffuse = b.new("ShaderNodeBsdfDiffuse")
    diffuse.label = "diffuse (Lambert)"
    b.link(value(spec["diffuse"]["color"]), diffuse.inputs["Color"])
    diffuse.inputs["Roughness"].default_value = 0.0
    b.link(value(spec["diffuse"]["normal"]), diffuse.inputs["Normal"])
    closures = add(spec_closure, diffuse.outputs["BSDF"], "scene closures")

    # the correction: the lights' terms (gated closures, in emission mode) here, the world's
    # in the correction group, fed the quantities it uses
    plan = b.lights
    correct = b.value(plan.scene["correct"])
    correct.node.label = "correct (not the closures' own switches)"
    group = b.new("ShaderNodeGroup")
    group.node_tree = correction_group
    group.label = "Correction (world) and residual albedo"
    group.width = 220
    for label, _, source in plan.correction.inputs:
        b.link(b.value(source), group.inputs[label])
        b.current_frame = frame
    b.mode = "emission"
    rest = b.value(plan.scene["correction_lights"])
    lights = _closures(b, {"correction_lights": plan.scene["correction_lights"]}, None, rest, frame)
    b.mode = "colour"
    correction = add(
        lights,
        group.outputs[CORRECTION_OUTPUTS["correction_world"][0]],
        "correction: the lights + the world",
    )
    scene = add(
        closures,
        mix(correct, None, correction, "correction (0: the closures are the model)"),
        "scene closures + correction",
    )
    residual = b.call("vec.SCALE", [group.outputs[CORRECTION_OUTPUTS["residual"][0]], scene_on])
    residual.node.label = "residual albedo (scene transport)"
    return mix(scene_on, lab, scene, "lab emission or scene closures"), residual


# --- The correction's and the residual albedo's tables (integrated here, once per cache) ----
#
# On the DFG table's axes (row j: pr = j/(N - 1), column i: n.v = i/(N - 1), at least
# ibl_bake.DFG_MIN_NDOTV), for each G the difference of its specular lobe from Smith's,
# dG = G - G_Smith, split by sign, each part's terms as the DFG table's: for the part P,
#   A_P = integral of dG_P D (1 - Fc) / (4 (n.l)(n.v)) (n.l) dl, B_P the same with Fc,
# so that integral of (f_G - f_Smith)_P (n.l) dl = specColor A_P + B_P (D and F >= 0), and
# the part's lobe (F = 1): c_P, the angle of its centroid from n toward the mirror side
# (in the plane of n and v), and x_P, the pre-filtered level whose GGX kernel (ibl_bake
# ggx_kernel) has the same mean cosine to its axis as the part has to its centroid. The
# split-sum of each part (its own direction and level) is what the correction's world term
# reads: the difference of two lobes changes sign (Cook-Torrance's G exceeds Smith's at
# grazing light, is below it at the specular peak of a grazing view), so one pre-filtered
# read of the signed difference would weigh light from the wrong directions.
#   residual_<G>: A_+ + A_-, B_+ + B_-, and the cosine-weighted mean of |Disney factor - 1|
#   positive_<G>: A_+, B_+, c_+
#   lobes_<G>:    x_+, c_-, x_-
# (Smith's own: zeros, but for the Disney column.) And the same for Disney's diffuse minus
# Lambert's (whatever the G), its factor's difference from 1, d = (1 + (fd90 - 1)(1 - n.l)^5)
# (1 + (fd90 - 1)(1 - n.v)^5) - 1, split by sign: M_P the cosine-weighted mean of d_P (so
# that integral of (f_Disney - f_Lambert)_P (n.l) dl = diffColor M_P), its centroid's angle
# and level as above:
#   disney_positive: M_+, c_+, x_+
#   disney_negative: M_-, c_-, x_-

SOURCE_HASH = "ctlab_source_hash"


GROUP_FILE = "node_group.blend"  # the cache entry's file: the group as built, no images


def source_digest() -> str:
    """What the group is built from: its description, the model's interface and this
    builder; with Blender's version, the cache key of the built group."""
    import hashlib

    return hashlib.sha256(
        DESCRIPTION.read_bytes()
        + repr(GROUP_INPUTS).encode()
        + repr(GROUP_OUTPUTS).encode()
        + Path(__file__).read_bytes()
    ).hexdigest()[:16]


def cache_key(digest: str) -> str:
    """The cache entry of the group built from ``digest`` by this Blender (a .blend written
    by one version is not read the same by an older one)."""
    return "node-group-{}-{}".format(digest, "_".join(str(v) for v in bpy.app.version))


def _group_names(name: str) -> tuple:
    """The group and the groups it holds, as build_group names them."""
    return (name, f"{name} Light", f"{name} Correction", f"{name} Pre-filtered")


def ensure_group() -> bpy.types.ShaderNodeTree:
    """The node group, built once: reused when this file has it, built from the current
    description (rebuilding would reset the inputs and links of every material using it);
    else appended from the cache, where the first build in any process put it
    (``cache_key``: 0.04 s against 3-18 s to build its 1,271 nodes, bench/results.md);
    else built, and put in the cache. A file holding an older group of ours is rebuilt in
    place, so that its materials keep it. An unusable cache folder only costs the build."""
    digest = source_digest()
    name = load_description()["group"]["name"]
    group = bpy.data.node_groups.get(name)
    if group is not None and group.get(TAG) and group.get(SOURCE_HASH) == digest:
        return group
    free = not any(n in bpy.data.node_groups for n in _group_names(name))
    if free:
        appended = _append_cached(digest, name)
        if appended is not None:
            return appended
    group = build_group()
    group[SOURCE_HASH] = digest
    if free:
        _store(digest, group)
    return group


def _append_cached(digest: str, name: str) -> bpy.types.ShaderNodeTree | None:
    """The group appended from its cache entry (with the groups it holds), or None where
    there is none (or the cache folder is unusable)."""
    from ..core import cache

    try:
        folder = cache.lookup(cache_key(digest))
    except UserError:
        return None
    if folder is None:
        return None
    with bpy.data.libraries.load(str(folder / GROUP_FILE), link=False) as (source, target):
        target.node_groups = [n for n in source.node_groups if n == name]
    [group] = target.node_groups
    if group.name != name or group.get(SOURCE_HASH) != digest or not group.get(TAG):
        raise UserError(f"the cache entry {folder} does not hold the node group {name!r}")
    return group


def _store(digest: str, group: bpy.types.ShaderNodeTree) -> None:
    """Put the group just built (no images yet: set_bake adds them) in the cache."""
    from ..core import cache

    def fill(staging: Path) -> None:
        bpy.data.libraries.write(str(staging / GROUP_FILE), {group}, compress=True)

    try:
        cache.build(cache_key(digest), fill)
    except UserError:
        pass  # no cache: the next process builds the group again


def set_bake(group: bpy.types.ShaderNodeTree, folder) -> None:
    """Point the group's texture nodes at a bake folder's files (core/ibl_bake.py), and the
    scene transport's tables at theirs (``correction_table_folder``, once per cache)."""
    folder = Path(folder)
    trees, pending = [], [group]  # and the groups it holds: per-light, correction
    while pending:
        tree = pending.pop()
        if tree not in trees:
            trees.append(tree)
            pending += [
                n.node_tree
                for n in tree.nodes
                if n.bl_idname == "ShaderNodeGroup"
                and n.node_tree is not None
                and (n.node_tree.get(LIGHT_GROUP) or n.node_tree.get(CORRECTION_GROUP))
            ]
    nodes = [node for tree in trees for node in tree.nodes]
    tables = correction_table_folder() if any(MODEL_TABLE in node for node in nodes) else None
    for node in nodes:
        # unchanged values are not set again: every change re-syncs each material using
        # the group (0.8 s a material, growing with the materials, where a conversion set
        # the shared group's bake again for each)
        if MODEL_TABLE in node:
            image = _float_image(tables / f"{node[MODEL_TABLE]}.exr")
            if node.image != image:
                node.image = image
        if BAKE_FILE not in node:
            continue
        path = folder / f"{node[BAKE_FILE]}.exr"
        if not path.is_file():
            raise UserError(f"the bake folder {folder} has no {path.name}; bake again")
        image = _float_image(path)
        if BAKE_DIM in node:
            size = float(image.size[0 if node[BAKE_DIM] == "width" else 1])
            if node.outputs[0].default_value != size:
                node.outputs[0].default_value = size
        elif node.image != image:
            node.image = image


def table_images() -> set:
    """The images the model's groups read (their tables and bakes, set_bake), in any file:
    the add-on makes them again from its cache when a material syncs."""
    return {
        node.image
        for group in bpy.data.node_groups
        if group.get(TAG) or group.get(LIGHT_GROUP) or group.get(CORRECTION_GROUP)
        for node in group.nodes
        if (BAKE_FILE in node or MODEL_TABLE in node) and getattr(node, "image", None)
    }


def _float_image(path: Path) -> bpy.types.Image:
    """A baked file or table as an image, packed into the .blend (Image.pack): the file
    renders the same on a machine without the add-on or its cache (a render farm), since
    Cycles and EEVEE read a packed image's own bytes. The image keeps the cache path, which
    need not exist there."""
    image = bpy.data.images.load(str(path), check_existing=True)
    if image.colorspace_settings.name != "Non-Color":  # setting it reloads the image
        image.colorspace_settings.name = "Non-Color"
    if image.use_half_precision:
        image.use_half_precision = False  # EEVEE: keep 32-bit floats on the GPU
    if image.packed_file is None:
        image.pack()
    return image
