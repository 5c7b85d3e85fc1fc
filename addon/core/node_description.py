"""The node group's description, node_groups/cook_torrance.toml, read without Blender.

The description is data: frames of named nodes written as nested calls (the file's header says
how). This module checks it against the model (core/model/words.py and core/model/interface.py:
its views, light slots, the scene transport's keys), parses each expression into a tree
('call', 'KIND.OP', [args]) / ('ref', name) / ('num', value), and plans the groups it is built
into: the per-light group (``LightPlan``) and the scene transport's correction group
(``SubgroupPlan``). The builder (addon/blender/node_group.py) turns those plans into Blender
nodes; the tests read them without Blender, as Blender's node_wrangler keeps its bpy-free
helpers apart."""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

from .errors import UserError
from .files import NODE_GROUPS_DIR
from .ibl_bake import DFG_SIZE
from .model import GROUP_INPUTS, LIGHT_SLOTS, VIEWS

DESCRIPTION = NODE_GROUPS_DIR / "cook_torrance.toml"
# Terms that the Emission output adds as closures which Cycles can skip (the file's header)
CLOSURE_OPS = ("gated", "prefiltered")
VECTOR_VALUE_OPS = {"DOT_PRODUCT", "LENGTH", "DISTANCE"}
# What the description's [scene] table must hold (the scene transport)
SCENE_KEYS = (
    "label",
    "on",
    "multi_ggx",
    "specular",
    "diffuse",
    "correct",
    "correction_lights",
    "correction_world",
    "residual",
)


def load_description(path: Path = DESCRIPTION) -> dict:
    with open(path, "rb") as f:
        data = tomllib.load(f)
    if list(data["views"]) != list(VIEWS):
        raise UserError(f"{path}: the views must be, in order: {', '.join(VIEWS)}")
    if data["lights"]["slots"] != LIGHT_SLOTS:
        raise UserError(
            f"{path}: it is written for {data['lights']['slots']} light slots; the "
            f"model has {LIGHT_SLOTS}"
        )
    if not set(SCENE_KEYS) <= set(data.get("scene", {})):
        raise UserError(
            f"{path}: its [scene] table needs label, on, multi_ggx, specular.*, "
            "diffuse.*, correct, correction_lights, correction_world and "
            "residual (the scene transport's closures, its correction and its "
            "residual albedo)"
        )
    if data["group"]["dfg_size"] != DFG_SIZE:
        raise UserError(
            f"{path}: its DFG lookups are written for {data['group']['dfg_size']}"
            f"-texel tables; ibl_bake makes {DFG_SIZE}"
        )
    return data


# --- Parsing -----------------------------------------------------------------------------

_TOKEN = re.compile(
    r"\s*(?:(?P<num>-?\d+\.?\d*(?:[eE][-+]?\d+)?)|(?P<name>[A-Za-z_][\w. !]*?)"
    r"(?=\s*[(),]|\s*$)|(?P<sym>[(),]))"
)


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

    def at(i):
        if i >= len(tokens):
            raise UserError(f"node description: {text!r} ends too early")
        return tokens[i]

    def expr(i):
        kind, value = at(i)
        if kind == "num":
            return ("num", float(value)), i + 1
        if kind != "name":
            raise UserError(f"node description: unexpected {value!r} in {text!r}")
        if i + 1 < len(tokens) and tokens[i + 1] == ("sym", "("):
            args, i = [], i + 2
            while at(i) != ("sym", ")"):
                arg, i = expr(i)
                args.append(arg)
                if at(i) == ("sym", ","):
                    i += 1
                elif at(i) != ("sym", ")"):
                    raise UserError(
                        f"node description: expected ',' or ')' after an argument in {text!r}"
                    )
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


def _per_light_names(data: dict) -> set:
    return {
        name for spec in data["frames"].values() if spec.get("per_light") for name in spec["nodes"]
    }


def _refs(tree, found: dict) -> dict:
    """The names an expression refers to, in the order they first appear (a dict: the
    group's sockets and nodes come out in the same order in every process)."""
    if tree[0] == "ref":
        found[tree[1]] = None
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
    return {i.group: ("FLOAT" if i.kind in ("FLOAT", "INT") else "VECTOR") for i in GROUP_INPUTS}


class LightPlan:
    """The description split for the per-light group: its inputs (the light's fields, then the
    other frames' quantities it uses), its node expressions and its outputs (the per-light
    nodes used elsewhere; a closure term's arguments as ``name.0``, ``name.1``...)."""

    def __init__(self, data: dict):
        self.slots = data["lights"]["slots"]
        self.key_sun = {field: parse(text) for field, text in data["lights"]["key"].items()}
        self.fields = list(self.key_sun)
        per_light = self.per_light = _per_light_names(data)
        main, sub, correction = {}, {}, {}
        for frame, spec in data["frames"].items():
            for name, text in spec["nodes"].items():
                tree = _all_lights(parse(text), per_light, self.slots)
                (
                    sub
                    if spec.get("per_light")
                    else correction
                    if spec.get("correction_group")
                    else main
                )[name] = (frame, tree)
        self.views = {
            view: _all_lights(parse(text), per_light, self.slots)
            for view, text in data["views"].items()
        }
        # the scene transport's expressions (the description's [scene])
        self.scene = {
            key: _all_lights(parse(data["scene"][key]), per_light, self.slots)
            for key in SCENE_EXPRESSIONS
        }
        used_outside = {}
        for tree in (
            [t for _, t in main.values()] + list(self.views.values()) + list(self.scene.values())
        ):
            used_outside |= _refs(tree, {})
        globals_used = []
        self.exprs = {}  # the per-light group's nodes
        for name, (frame, tree) in sub.items():
            for ref in _refs(tree, {}):
                if ref.startswith("light."):
                    if ref[6:] not in self.key_sun:
                        raise UserError(f"node description: the key Sun has no {ref[6:]!r}")
                elif ref in main and ref not in globals_used:
                    globals_used.append(ref)
            self.exprs[name] = (frame, self._localise(tree, main))
        kinds = _input_kinds()
        field_kinds = {f: kinds[f"Light 1 {f}"] for f in self.fields}
        self.globals = globals_used
        self.inputs = [(f, field_kinds[f]) for f in self.fields] + [
            (g, _kind(main[g][1], main, kinds)) for g in globals_used
        ]
        self.outputs = []
        self.closures = {}  # per-light closure term -> (op, argument count)
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
        self.correction = SubgroupPlan(
            correction, {key: self.scene[key] for key in CORRECTION_OUTPUTS}, main, kinds
        )

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
            for name, _ in self.outputs:
                if "." not in name:
                    exprs[name + suffix] = ("lights", ("light", suffix, name))
            for name, (op, count) in self.closures.items():
                exprs[name + suffix] = (
                    "lights",
                    ("call", op, [("light", suffix, f"{name}.{k}") for k in range(count)]),
                )
        return exprs


# --- The correction group (the description's frames marked correction_group) ------------
#
# The scene transport's correction for the world and its residual albedo are built into a
# group of their own ("<group> Correction"), like the per-light frames, whose inputs are the
# main group's quantities they use and whose outputs are the world's correction (a shader:
# its pre-filtered terms as chains of Mix Shader nodes) and the residual albedo: its many
# texture lookups would make the main tree slow to build.

# [scene] expressions: the Mix Shader's factor, the lights' terms (main group), the world's
# terms and the residual (the correction group's outputs)
SCENE_EXPRESSIONS = ("correct", "correction_lights", "correction_world", "residual")
CORRECTION_OUTPUTS = {
    "correction_world": ("Correction", "SHADER"),
    "residual": ("Residual Albedo", "RGBA"),
}


class SubgroupPlan:
    """Frames built into a group of their own, over the main group's quantities: their node
    expressions with each main node or group input they use as an input of that group
    (``inputs``: (socket name, kind, the main group's expression that feeds it)), and the
    roots it outputs (``roots``: key -> expression)."""

    def __init__(self, exprs: dict, roots: dict, main: dict, kinds: dict):
        self.inputs, seen = [], set()

        def localise(tree):
            if tree[0] == "ref":
                name = tree[1]
                if name in exprs or name.startswith("geo."):
                    return tree
                label = name[3:] if name.startswith("in.") else name
                if name.startswith("in."):
                    kind = kinds[label]
                elif name in main:
                    kind = _kind(main[name][1], main, kinds)
                else:
                    raise UserError(
                        f"node description: the correction group cannot use "
                        f"{name!r} (a per-light node)"
                    )
                if label not in seen:
                    seen.add(label)
                    self.inputs.append((label, kind, tree))
                return ("ref", "in." + label)
            if tree[0] == "call":
                files = 1 if tree[1] in ("env", "table") else 0  # a baked file's name
                return ("call", tree[1], tree[2][:files] + [localise(a) for a in tree[2][files:]])
            return tree

        self.exprs = {name: (frame, localise(tree)) for name, (frame, tree) in exprs.items()}
        self.roots = {key: localise(tree) for key, tree in roots.items()}
