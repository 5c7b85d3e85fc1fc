"""The Cook-Torrance node group, assembled from its description, node_groups/cook_torrance.toml.

The description is data: frames of named nodes written as nested calls (see the file's header),
read, checked, parsed and planned without Blender by core/node_description.py; its expressions
become nodes through blender/node_compiler.py. This module assembles the groups: the main
group, whose sockets are the model's interface (core.model.GROUP_INPUTS) and whose View input
selects the view; the per-light group; the correction group and its pre-filtered chain. With
Light Transport Scene = 1 and the full view, the Emission output is the model as Cycles
closures instead, plus the correction emission (the description's [scene],
``_scene_transport``). The group is built once and cached (``ensure_group``); ``set_bake``
loads the baked split-sum files (core/ibl_bake.py) and the scene transport's tables
(core/correction_tables.py) as packed images.
"""

from __future__ import annotations

import json
from pathlib import Path

import bpy

from ..core.errors import UserError
from ..core.files import DATA_DIR
from ..core.source_code import code_bytes
from ..core.model import GROUP_INPUTS, GROUP_OUTPUTS, SCENE_VIEWS, VIEWS
from ..core import node_description
from ..core.node_description import (
    CORRECTION_OUTPUTS,
    DESCRIPTION,
    LightPlan,
    SubgroupPlan,
    load_description,
    parse,
)
from . import node_closures, node_compiler, owned
from .group_images import _float_image, set_bake, table_images  # noqa: F401 (their home)
from .node_compiler import BAKE_DIM, BAKE_FILE, MODEL_TABLE  # noqa: F401 (their tags)
from .node_closures import chain, closures
from .node_compiler import CHAIN_INPUTS, Compiler

# The groups' tags, their roles (blender/owned.py): found by identity, never by name alone
TAG = owned.NODE_GROUP
LIGHT_GROUP = owned.LIGHT_GROUP  # tags the per-light group
CORRECTION_GROUP = owned.CORRECTION_GROUP  # tags the correction group and its chain
# The group's output of the residual albedo (core.model OSL_RESIDUAL), built where the
# interface (core.model GROUP_OUTPUTS) has it
RESIDUAL_OUTPUT = "Residual Albedo"
SOURCE_HASH = "ctlab_source_hash"
GROUP_FILE = "node_group.blend"  # the cache entry's file: the group as built, no images
SHIPPED = DATA_DIR / GROUP_FILE  # the group as built, shipped (ensure_group)
SHIPPED_SOURCES = DATA_DIR / "node_group.json"  # its source digest and Blender version

SOCKET_TYPES = {
    "FLOAT": "NodeSocketFloat",
    "INT": "NodeSocketInt",
    "RGBA": "NodeSocketColor",
    "VECTOR": "NodeSocketVector",
    "SHADER": "NodeSocketShader",
}


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


def _tree(name: str, role: str, tag: str = "") -> bpy.types.ShaderNodeTree:
    """The add-on's shader node tree of that name and role (owned.find), emptied, or a new
    one (named "<name>.001" where a user's block holds the name: a user's is never
    rebuilt); tagged ``tag`` (the role's, by default) as before the mark."""
    group = owned.find(bpy.data.node_groups, name, role, lambda g: g.bl_idname == "ShaderNodeTree")
    if group is None:
        group = owned.new(bpy.data.node_groups, name, role, "ShaderNodeTree")
    group[tag or role] = True
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
    b = Compiler(group, data, plan.exprs)
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
    ``closures`` builds them) and the residual albedo (a colour)."""
    group = _tree(name, CORRECTION_GROUP)
    group.description = (
        "The scene transport's correction for the world and its residual "
        "albedo (Cook-Torrance Lab; node_groups/cook_torrance.toml)"
    )
    for label, kind, _ in plan.inputs:
        group.interface.new_socket(label, in_out='INPUT', socket_type=SOCKET_TYPES[kind])
    for label, kind in CORRECTION_OUTPUTS.values():
        group.interface.new_socket(label, in_out='OUTPUT', socket_type=SOCKET_TYPES[kind])
    b = Compiler(group, data, plan.exprs)
    b.chain_group = chain_group
    b.group_in.location = (-600, 0)
    b.current_frame = frame = "correction"
    b.mode = "emission"
    rest = b.value(plan.roots["correction_world"])
    world = closures(b, {"correction_world": plan.roots["correction_world"]}, None, rest, frame)
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
    b = Compiler(group, data, plan.main_exprs(), plan, light_group)
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
    emission = closures(b, views, view_on, select("emission"))
    emission, residual = _scene_transport(b, data["scene"], view_on, emission, correction_group)
    out = group.nodes.new("NodeGroupOutput")
    out.location = (2800, 0)
    group.links.new(emission, out.inputs["Emission"])
    group.links.new(colour, out.inputs["Value"])
    if RESIDUAL_OUTPUT in out.inputs:
        group.links.new(residual, out.inputs[RESIDUAL_OUTPUT])
    return group


def build_chain_group(data: dict, name: str) -> bpy.types.ShaderNodeTree:
    """prefiltered(Level, Direction, Colour) as Emission closures behind Mix Shader nodes,
    a group of its own (tagged as the correction group, so that set_bake finds its
    lookups)."""
    group = _tree(name, owned.PREFILTERED_GROUP, CORRECTION_GROUP)
    group.description = (
        "The pre-filtered levels toward a direction at a fractional level, "
        "times a colour, as Emission closures (Cook-Torrance Lab)"
    )
    for label, kind in CHAIN_INPUTS:
        group.interface.new_socket(label, in_out='INPUT', socket_type=SOCKET_TYPES[kind])
    group.interface.new_socket("Emission", in_out='OUTPUT', socket_type=SOCKET_TYPES["SHADER"])
    b = Compiler(group, data, {})
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
    group.links.new(chain(b, *sockets, "prefiltered", emit, mix), out.inputs["Emission"])
    return group


def _scene_transport(b: Compiler, spec: dict, view_on: list, lab, correction_group):
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
    emission (``closures``), so Cycles skips a light's term where n.l <= 0 and reads two
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

    mix = b.mix_shader

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
    model_closures = add(spec_closure, diffuse.outputs["BSDF"], "scene closures")

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
    lights = closures(b, {"correction_lights": plan.scene["correction_lights"]}, None, rest, frame)
    b.mode = "colour"
    correction = add(
        lights,
        group.outputs[CORRECTION_OUTPUTS["correction_world"][0]],
        "correction: the lights + the world",
    )
    # the correction's reach: hits of a ray depth below Correction Depth
    path = b.new("ShaderNodeLightPath")
    reach = b.call("math.LESS_THAN", [path.outputs["Ray Depth"], b.socket("in.Correction Depth")])
    reach.node.label = "ray depth < Correction Depth"
    b.current_frame = frame
    correct = b.call("math.MULTIPLY", [correct, reach])
    correct.node.label = "correct here"
    scene = add(
        model_closures,
        mix(correct, None, correction, "correction (0: the closures are the model)"),
        "scene closures + correction",
    )
    residual = b.call("vec.SCALE", [group.outputs[CORRECTION_OUTPUTS["residual"][0]], scene_on])
    residual.node.label = "residual albedo (scene transport)"
    return mix(scene_on, lab, scene, "lab emission or scene closures"), residual


def source_digest() -> str:
    """What the group is built from: its description, the model's interface, its planning
    (core/node_description.py), this assembly, the compiler and the closures; with Blender's
    version, the cache key of the built group. The description counts as its parsed data and
    each module as its code (core/source_code.py), so a comment or a docstring changes
    nothing."""
    import hashlib
    import tomllib

    description = json.dumps(tomllib.loads(DESCRIPTION.read_text()), sort_keys=True)
    modules = (Path(__file__), Path(node_compiler.__file__), Path(node_closures.__file__))
    modules += (Path(node_description.__file__),)
    return hashlib.sha256(
        description.encode()
        + repr(GROUP_INPUTS).encode()
        + repr(GROUP_OUTPUTS).encode()
        + b"".join(code_bytes(p) for p in modules)
    ).hexdigest()[:16]


def cache_key(digest: str) -> str:
    """The cache entry of the group built from ``digest`` by this Blender (a .blend written
    by one version is not read the same by an older one)."""
    return "node-group-{}-{}".format(digest, "_".join(str(v) for v in bpy.app.version))


def _group_roles(name: str) -> tuple:
    """The group and the groups it holds, as build_group names them, with their roles."""
    return (
        (name, TAG),
        (f"{name} Light", LIGHT_GROUP),
        (f"{name} Correction", CORRECTION_GROUP),
        (f"{name} Pre-filtered", owned.PREFILTERED_GROUP),
    )


def ensure_group() -> bpy.types.ShaderNodeTree:
    """The node group, built once: reused when this file has it, built from the current
    description (rebuilding would reset the inputs and links of every material using it);
    else appended from the cache, where the first build in any process put it
    (``cache_key``), or from the group the extension ships (``SHIPPED``, written by
    scripts/build_node_group.py with the oldest Blender series, so that every series reads
    it) where it was built from the same sources: 0.05 s against 3-18 s to build its 1,271
    nodes (bench/results.md); else built, and put in the cache. A file holding an older
    group of ours is rebuilt in place, so that its materials keep it. An unusable cache
    folder only costs the build. The groups are the add-on's own (blender/owned.py): a
    user's group of one of their names is never used or rebuilt; ours takes "<name>.001"."""
    digest = source_digest()
    name = load_description()["group"]["name"]
    roles = _group_roles(name)
    group = owned.find(bpy.data.node_groups, name, TAG)
    if group is not None and group.get(SOURCE_HASH) == digest:
        return group
    free = not any(owned.find(bpy.data.node_groups, n, role) for n, role in roles)
    if free:
        appended = _append_cached(digest, name) or _append_shipped(digest, name)
        if appended is not None:
            return appended
    group = build_group()
    group[SOURCE_HASH] = digest
    groups = bpy.data.node_groups
    if free and all(groups.get(n) == owned.find(groups, n, r) for n, r in roles):
        _store(digest, group)  # under its own names, which _append looks for
    return group


def shipped_digest() -> str | None:
    """The source digest of the shipped group (SHIPPED_SOURCES), or None without one."""
    try:
        return json.loads(SHIPPED_SOURCES.read_text())["digest"]
    except (OSError, ValueError, KeyError, TypeError):
        return None


def _append_shipped(digest: str, name: str) -> bpy.types.ShaderNodeTree | None:
    """The shipped group appended, where it was built from these sources."""
    return _append(SHIPPED, digest, name) if shipped_digest() == digest else None


def _append_cached(digest: str, name: str) -> bpy.types.ShaderNodeTree | None:
    """The group appended from its cache entry (with the groups it holds), or None where
    there is none (or the cache folder is unusable)."""
    from ..core import cache

    try:
        folder = cache.lookup(cache_key(digest))
    except UserError:
        return None
    return None if folder is None else _append(folder / GROUP_FILE, digest, name)


def _append(path: Path, digest: str, name: str) -> bpy.types.ShaderNodeTree:
    """The group ``name`` (with the groups it holds) appended from a .blend ctlab wrote;
    Blender renames an appended group whose name a user's block holds ("<name>.001")."""
    with bpy.data.libraries.load(str(path), link=False) as (source, target):
        target.node_groups = [n for n in source.node_groups if n == name]
    group = target.node_groups[0] if len(target.node_groups) == 1 else None
    if group is None or group.get(SOURCE_HASH) != digest or not owned.is_ours(group, TAG):
        raise UserError(f"{path} does not hold the node group {name!r}")
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
