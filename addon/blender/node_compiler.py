"""Shader nodes from the node description's expressions: a compiler from the parsed nested
calls of node_groups/cook_torrance.toml (core/node_description.py ``parse``) into Blender
shader nodes, wired, each in the frame of its term.

``Compiler`` turns an expression into nodes: ``math.*`` and ``vec.*`` into Math and Vector
Math nodes, ``vec3``, ``x``/``y``/``z``, ``pick``/``vpick``, ``rotz``; ``env`` and ``table``
into Environment Texture lookups of a baked file or table (tagged with BAKE_FILE, BAKE_DIM,
MODEL_TABLE for node_group.set_bake to fill); ``light.*`` into instances of the per-light
group; the closure terms (``gated``, ``prefiltered``, core.node_description CLOSURE_OPS)
either as colours or, in emission mode, left for ``closures`` to add as Emission closures
behind Mix Shader nodes that Cycles can skip. What the nodes make (the group, its sockets,
its sub-groups) is blender/node_group.py's.
"""

from __future__ import annotations

import bpy

from ..core.correction_tables import CORRECTION_TABLES
from ..core.errors import UserError
from ..core.ibl_bake import LEVEL_COUNT
from ..core.node_description import CLOSURE_OPS, VECTOR_VALUE_OPS, LightPlan

BAKE_FILE = "ctlab_bake_file"  # texture nodes: which baked file they read
BAKE_DIM = "ctlab_bake_dim"  # value nodes: that file's width or height
MODEL_TABLE = "ctlab_model_table"  # texture nodes: which correction table they read
POLE_MARGIN = 3e-3  # radians: the least distance of a lat-long lookup from a pole
# added to a lookup direction's x (environment()): h > 0 at a pole, its square a normal float32
POLE_NUDGE = 1e-18
# The correction group's pre-filtered terms are instances of one group of the chain (its
# many lookups built once)
CHAIN_INPUTS = (("Level", "FLOAT"), ("Direction", "VECTOR"), ("Colour", "VECTOR"))


class Compiler:
    """Expressions of one tree's description into its nodes: ``value`` of a parsed
    expression is a socket (or a constant), each named node built once per mode."""

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
            # a number for every component, or a vector constant (x, y, z)
            xyz = tuple(value) if isinstance(value, tuple) else (value,) * 3
            sock.default_value = xyz if len(sock.default_value) == 3 else xyz + (1.0,)
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
        pi/2 - delta: its horizontal part h is scaled by k = max(1, |d.z| tan(delta) / h).

        delta is half a row, pi/(2H), but at least POLE_MARGIN: Cycles finds t from
        acos(d.z / |d|) in float32, which cannot resolve half a row of a tall image (at
        H = 1024 it overshot the last row's centre by 1% of a row, at H = 4096 by half a
        row). For H > 524 the lookup reads a little below the last row's centre instead.

        Per direction, once: d' = d + (POLE_NUDGE, 0, 0), so that h > 0 everywhere. Away
        from the poles the nudge is below float32's resolution of d.x (or, where d.x is 0,
        of atan2); exactly at a pole (h = 0, a flat floor's normal) k scales it to the
        horizontal part |d.z| tan(delta) along +x, where the model's s is 0.5 as well. Then
        per file only k and d' (k, k, 1): four nodes."""
        if d not in self.horizontal:
            nudged = self.call("vec.ADD", [d, (POLE_NUDGE, 0.0, 0.0)])
            flat = self.call("vec.MULTIPLY", [nudged, (1.0, 1.0, 0.0)])
            # (at least the nudge: where d.x is exactly -POLE_NUDGE, never a division by 0)
            h = self.call("math.MAXIMUM", [self.call("vec.LENGTH", [flat]), POLE_NUDGE])
            abs_z = self.call("math.ABSOLUTE", [self.call("z", [d])])
            self.horizontal[d] = (nudged, self.call("math.DIVIDE", [abs_z, h]))
        nudged, z_over_h = self.horizontal[d]
        delta = self.call(
            "math.MAXIMUM",
            [
                self.call("math.DIVIDE", [1.5707963267948966, self.dimension(key, "height")]),
                POLE_MARGIN,
            ],
        )
        k = self.call(
            "math.MAXIMUM",
            [1.0, self.call("math.MULTIPLY", [z_over_h, self.call("math.TANGENT", [delta])])],
        )
        scale = self.call("vec3", [k, k, 1.0])
        return self.lookup(key, self.call("vec.MULTIPLY", [nudged, scale]))

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
        Read by an Environment Texture node toward a direction that Blender's
        equirectangular mapping takes to (u, v): azimuth phi = 2 pi (0.5 - u), elevation
        theta = pi (v - 0.5), as d = (cos phi, sin phi, tan theta), whose elevation
        atan2(tan theta, 1) is theta (|theta| < pi/2 half a texel inside the edges): one
        bilinear lookup without mip-maps in both Cycles and EEVEE (an Image Texture node's
        Linear lookups use mip-maps in EEVEE). The round trip through the angles costs up to
        about 5e-5 of a texel in float32; (u, v) stays half a texel inside the edges, so the
        wrapped neighbour's weight is at most about 5e-6."""
        if (u, v) not in self.table_directions:  # one direction for the tables at (u, v)
            phi = self.call("math.MULTIPLY_ADD", [u, -6.283185307179586, 3.141592653589793])
            theta = self.call("math.MULTIPLY_ADD", [v, 3.141592653589793, -1.5707963267948966])
            self.table_directions[u, v] = self.call(
                "vec3",
                [
                    self.call("math.COSINE", [phi]),
                    self.call("math.SINE", [phi]),
                    self.call("math.TANGENT", [theta]),
                ],
            )
        return self.lookup(key, self.table_directions[u, v])
