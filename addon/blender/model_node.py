"""The model's node in a material, behind one interface whichever implementation carries it:
the OSL script node (osl/cook_torrance.osl) or the node group (node_groups/cook_torrance.toml).

Every caller (materials, the scene builder, light sync, conversion, the UI) creates, reads
and sets the model through these functions; this is the only module that asks which
implementation a node is. The inputs are those of core.model: the surface inputs and the
key-light and world inputs have the same socket names in both; the view and the switches are
strings in OSL and integer inputs in the group; files (the HDRI, its tables and bake) are OSL
inputs, or the group's texture images. A material "uses the model" when ``find`` returns a
node.
"""

from __future__ import annotations

import bpy

from . import drivers, node_group, osl_shader
from ..core.errors import UserError
from ..core.model import (
    BAKED_IBL_MODES,
    BY_KEY,
    IMPLEMENTATIONS,
    LIGHT_FIELDS,
    LIGHT_SLOTS,
    LIGHTING,
    OPTION_VALUES,
    OPTIONS,
    OSL_RESIDUAL,
    SURFACE,
    TRANSPORT,
    Lighting,
    ModelOptions,
    indirect_light,
    light_key,
    resolve,
)

NODE_NAME = "Cook-Torrance"
# custom property of the AOV Output connect_residual makes (its pass name): the mark that
# says the add-on made it, so remove_residual never removes a user's node of that pass
RESIDUAL_AOV = "ctlab_residual_aov"
SURFACE_KEYS = tuple(i.key for i in SURFACE)
OPTION_KEYS = tuple(i.key for i in OPTIONS)
LIGHTING_KEYS = tuple(i.key for i in LIGHTING)
TRANSPORT_KEYS = tuple(i.key for i in TRANSPORT)


def implementation(node: bpy.types.Node) -> str | None:
    """ "osl", "nodes", or None when the node is not the model."""
    script = osl_shader.script_node(node)
    if script is not None:
        text = script.script
        if text is not None and text.name.startswith(osl_shader.TEXT_NAME):
            return "osl"
    elif node.bl_idname == "ShaderNodeGroup":
        if node.node_tree is not None and node.node_tree.get(node_group.TAG):
            return "nodes"
    return None


def find(mat: bpy.types.Material | None) -> bpy.types.Node | None:
    """The material's Cook-Torrance node, or None when the material does not use the model."""
    if mat is None or mat.node_tree is None:
        return None
    return next((n for n in mat.node_tree.nodes if implementation(n)), None)


def model_materials():
    """Every material in the file that uses the model, with its node."""
    for mat in bpy.data.materials:
        node = find(mat)
        if node is not None:
            yield mat, node


def _input(node: bpy.types.Node, key: str) -> bpy.types.NodeSocket:
    i = BY_KEY[key]
    if implementation(node) == "osl":
        return osl_shader.socket(node, i.osl)
    return node.inputs[i.group]


def surface_input(node: bpy.types.Node, key: str) -> bpy.types.NodeSocket:
    """The socket of a surface input (albedo, metallic, smoothness, normal)."""
    if key not in SURFACE_KEYS:
        raise KeyError(key)
    return _input(node, key)


def lighting_input(node: bpy.types.Node, key: str) -> bpy.types.NodeSocket:
    """The socket of a key-light or world input (core.model LIGHTING: sun_to_light, ...)."""
    if key not in LIGHTING_KEYS:
        raise KeyError(key)
    return _input(node, key)


def transport_input(node: bpy.types.Node, key: str) -> bpy.types.NodeSocket:
    """The socket of an input of the scene transport both implementations have (core.model
    TRANSPORT: correction_depth)."""
    if key not in TRANSPORT_KEYS:
        raise KeyError(key)
    return _input(node, key)


def shader_output(node: bpy.types.Node) -> bpy.types.NodeSocket:
    if implementation(node) == "osl":
        return osl_shader.socket(node, "BSDF", output=True)
    return node.outputs["Emission"]


# --- Creating ----------------------------------------------------------------------------


def new_node(tree: bpy.types.NodeTree, impl: str) -> bpy.types.Node:
    """A new Cook-Torrance node of the given implementation in ``tree`` (unlinked); the node
    group's indirect light starts as split_sum (it has no reference mode)."""
    if impl == "osl":  # the shared compiled shader (osl_shader.shared_group)
        node = tree.nodes.new("ShaderNodeGroup")
        node.node_tree = osl_shader.shared_group()
        node.width = 220
    elif impl == "nodes":
        node = tree.nodes.new("ShaderNodeGroup")
        node.node_tree = node_group.ensure_group()
        node.width = 220
    else:
        raise UserError(
            f"unknown implementation {impl!r}; choose one of: {', '.join(IMPLEMENTATIONS)}"
        )
    node.name = node.label = NODE_NAME
    return node


def connect_output(tree: bpy.types.NodeTree, node: bpy.types.Node) -> bpy.types.Node:
    """A Material Output fed by the model: for Cycles only with the OSL shader (EEVEE cannot
    run it), for every engine with the group. The residual albedo pass is not wired here: it
    costs every camera hit its inputs, so only a scene that asks for it gets it
    (light_sync.set_residual_pass)."""
    out = tree.nodes.new("ShaderNodeOutputMaterial")
    out.location = (node.location.x + 400, node.location.y)
    out.target = 'CYCLES' if implementation(node) == "osl" else 'ALL'
    tree.links.new(shader_output(node), out.inputs["Surface"])
    return out


def residual_output(node: bpy.types.Node) -> bpy.types.NodeSocket | None:
    """The model's residual albedo output (core.model OSL_RESIDUAL): the OSL shader's, or the
    node group's Residual Albedo where its interface has one (core.model GROUP_OUTPUTS);
    None when the node has none."""
    if implementation(node) == "osl":
        try:
            return osl_shader.socket(node, OSL_RESIDUAL, output=True)
        except KeyError:
            return None
    if implementation(node) == "nodes":
        return node.outputs.get(node_group.RESIDUAL_OUTPUT)
    return None


def _residual_aovs(node: bpy.types.Node) -> list:
    """The AOV Output nodes connect_residual gave the node (its mark RESIDUAL_AOV, never a
    user's AOV Output of the same pass name)."""
    residual = residual_output(node)
    return [
        link.to_node
        for link in (residual.links if residual is not None else ())
        if link.to_node.bl_idname == "ShaderNodeOutputAOV"
        and link.to_node.get(RESIDUAL_AOV) == OSL_RESIDUAL
    ]


def has_residual(node: bpy.types.Node) -> bool:
    """Whether connect_residual wired the node's residual albedo to the pass."""
    return bool(_residual_aovs(node))


def connect_residual(tree: bpy.types.NodeTree, node: bpy.types.Node) -> None:
    """The model's residual albedo (``residual_output``) into an AOV Output named
    core.model OSL_RESIDUAL, so a view layer with that AOV shows it as a render pass (once:
    a node already wired keeps its AOV Output)."""
    residual = residual_output(node)
    if residual is None or has_residual(node):
        return
    aov = tree.nodes.new("ShaderNodeOutputAOV")
    aov.location = (node.location.x + 400, node.location.y - 200)
    aov.aov_name = OSL_RESIDUAL
    aov[RESIDUAL_AOV] = OSL_RESIDUAL
    tree.links.new(residual, aov.inputs["Color"])


def remove_residual(tree: bpy.types.NodeTree, node: bpy.types.Node) -> None:
    """Remove the AOV Output that connect_residual gave the node (an AOV Output it did not
    make stays, with its link)."""
    for aov in _residual_aovs(node):
        tree.nodes.remove(aov)


def link_geometry_normal(tree: bpy.types.NodeTree, node: bpy.types.Node) -> None:
    """The OSL shader reads its normal from a socket: feed it the geometry's when unlinked
    (the node group falls back to the geometry normal by itself)."""
    sock = surface_input(node, "normal")
    if implementation(node) == "osl" and not sock.is_linked:
        geometry = tree.nodes.new("ShaderNodeNewGeometry")
        geometry.location = (node.location.x - 250, node.location.y - 350)
        tree.links.new(geometry.outputs["Normal"], sock)
    set_normal_derivatives(node)


def set_normal_derivatives(node: bpy.types.Node) -> None:
    """OSL: whether the Normal input keeps its derivatives (core.model normal_derivatives,
    osl/cook_torrance.osl without_derivatives). Kept where the geometry's normal feeds it
    (they cost nothing there, and dropping them costs the render about 5%); dropped where
    other nodes do, such as a normal map, which would otherwise run with derivatives at about
    twice its cost. The rendered values are the same either way. A node of an earlier shader
    without the input is left as it is."""
    if implementation(node) != "osl":
        return
    normal = surface_input(node, "normal")
    keep = not normal.is_linked or normal.links[0].from_node.bl_idname == "ShaderNodeNewGeometry"
    try:
        flag = _input(node, "normal_derivatives")
    except KeyError:
        return
    if flag.default_value != int(keep):  # a write re-syncs (recompiles) the shader
        flag.default_value = int(keep)


# --- The view and the switches ---------------------------------------------------------


def get_option(node: bpy.types.Node, key: str) -> str:
    values = OPTION_VALUES[key]
    value = _input(node, key).default_value
    if implementation(node) == "osl":
        return value if value in values else values[0]
    if key == "ibl":  # the group's IBL Mode indexes BAKED_IBL_MODES
        return BAKED_IBL_MODES[min(max(int(value), 0), len(BAKED_IBL_MODES) - 1)]
    return values[min(max(int(value), 0), len(values) - 1)]


def _check_option(key: str, value: str) -> None:
    values = OPTION_VALUES[key]
    if value not in values:
        raise UserError(
            f"unknown {key.replace('_', ' ')} {value!r}; choose one of: {', '.join(values)}"
        )


def set_option(node: bpy.types.Node, key: str, value: str) -> None:
    """Set a switch or the view; an unknown value, or the reference IBL on the node group,
    is a UserError that says what to choose."""
    _check_option(key, value)
    if implementation(node) == "osl":
        osl_shader.set_strings(node, {BY_KEY[key].osl: value})
        return
    sock = _input(node, key)
    if key == "ibl":
        if value not in BAKED_IBL_MODES:
            raise UserError(
                f"the node group has no {value!r} indirect light (it cannot "
                "integrate an HDRI); use one of: "
                + ", ".join(BAKED_IBL_MODES)
                + ", or switch to the OSL implementation"
            )
        sock.default_value = BAKED_IBL_MODES.index(value)
    else:
        sock.default_value = OPTION_VALUES[key].index(value)


def set_defaults(node: bpy.types.Node, context: str, **options) -> None:
    """Set ``options`` (key -> value; None: the rule's) on ``node`` with the defaults and
    fallbacks that the model's rules give its implementation in ``context``
    (core.model.rules.resolve: the context's light transport, the implementation's indirect
    light). Raises UserError where the rules refuse the options."""
    osl = implementation(node) == "osl"
    strings = {}  # the OSL node's switches, set at once (its shared group changes once)
    for key, value in resolve(implementation(node), options, context).items():
        if key == "env_samples":  # a number, not a switch (the OSL shader's only)
            _input(node, key).default_value = int(value)
        elif osl:
            _check_option(key, value)
            strings[BY_KEY[key].osl] = value
        else:
            set_option(node, key, value)
    if strings:
        osl_shader.set_strings(node, strings)


# The OSL shader's settings of its integration, which ModelOptions carries (the node group has
# none: it integrates nothing per shading point)
OSL_SETTINGS = ("env_samples", "env_visibility", "one_sample", "sun_shadow", "shadow_rays", "seed")


def set_options(node: bpy.types.Node, options: ModelOptions) -> None:
    """The view, the switches and (OSL) the reference integrator's settings."""
    if implementation(node) != "osl":
        for key in OPTION_KEYS:
            set_option(node, key, getattr(options, key))
        return
    for key in OPTION_KEYS:  # one change of the node's strings (its shared group)
        _check_option(key, getattr(options, key))
    osl_shader.set_strings(node, {BY_KEY[k].osl: getattr(options, k) for k in OPTION_KEYS})
    for key in OSL_SETTINGS:
        _input(node, key).default_value = getattr(options, key)


# --- Lighting --------------------------------------------------------------------------


def set_lighting(node: bpy.types.Node, lighting: Lighting) -> None:
    """The key light's and the world's values, then its files (``set_environment``)."""
    for i in LIGHTING:
        value = getattr(lighting, i.key)
        _input(node, i.key).default_value = tuple(value) + (1.0,) if i.kind == "RGBA" else value
    set_lights(node, lighting.lights)
    set_environment(node, lighting.hdri, lighting.env_tables, lighting.ibl_bake)


def set_light_slot(node: bpy.types.Node, slot: int, values: dict | None) -> None:
    """Light slot ``slot`` (1-based) from core.lights.slot_values, or empty for None. The node
    group has no shadow switch (it cannot trace)."""
    for f in LIGHT_FIELDS:
        i = BY_KEY[light_key(slot, f)]
        value = i.default if values is None else values[f]
        if implementation(node) != "osl" and not i.group:
            continue
        if i.kind == "RGBA" and len(value) == 3:
            value = tuple(value) + (1.0,)
        _input(node, i.key).default_value = value


def set_lights(node: bpy.types.Node, lights) -> None:
    """The slots from a list of core.lights.Light (at most LIGHT_SLOTS, in slot order); the
    slots after them are emptied."""
    from ..core.lights import slot_values

    lights = list(lights)
    if len(lights) > LIGHT_SLOTS:
        raise UserError(f"{len(lights)} lights; the model shades at most {LIGHT_SLOTS}")
    for slot in range(1, LIGHT_SLOTS + 1):
        light = lights[slot - 1] if slot <= len(lights) else None
        set_light_slot(node, slot, slot_values(light) if light else None)


def set_environment(node: bpy.types.Node, hdri, tables: dict | None = None, bake=None) -> None:
    """Point the node at the world's HDRI and what is derived from it: the OSL shader at the
    file, its importance tables (reference IBL) and its bake folder (split-sum and Unity IBL);
    the group's textures at the bake. Arguments left None keep what the node has."""
    if implementation(node) == "osl":
        osl_shader.set_texture_convention(node)  # a file saved by another Blender
        files = {}
        if tables is not None:
            for key, name in (
                ("env_marginal", "marginal"),
                ("env_conditional", "conditional"),
                ("env_pdf_table", "pdf"),
            ):
                files[BY_KEY[key].osl] = str(tables.get(name, ""))
        osl_shader.set_environment(node, hdri, bake, files)
    elif bake:
        node_group.set_bake(node.node_tree, bake)


def add_drivers(tree, node, sun, world) -> int:
    """Drive the key light from a Sun object and the world inputs from the world's nodes."""
    return drivers.add_drivers(tree, node, sun, world)


def remove_drivers(tree, node) -> int:
    return drivers.remove_drivers(tree, node)


# --- Changing implementation ----------------------------------------------------------


def carry_input(
    tree: bpy.types.NodeTree, src: bpy.types.NodeSocket, dst: bpy.types.NodeSocket
) -> None:
    """Give ``dst`` what feeds ``src``: its link, else its value."""
    if src.is_linked:
        tree.links.new(src.links[0].from_socket, dst)
    else:
        dst.default_value = src.default_value


def _is_geometry_normal(sock: bpy.types.NodeSocket) -> bool:
    return (
        sock.bl_idname.startswith("NodeSocketVector")
        and sock.node.bl_idname == "ShaderNodeNewGeometry"
        and sock.name == "Normal"
    )


def replace_node(tree: bpy.types.NodeTree, old: bpy.types.Node, impl: str) -> bpy.types.Node:
    """Replace the model node ``old`` by one of implementation ``impl``, keeping every link and
    value of the surface inputs, the options, the scene transport's inputs (TRANSPORT) and
    the output links. The reference IBL becomes
    split_sum on the node group. Drivers on ``old`` are removed (light sync adds them again)."""
    new = new_node(tree, impl)
    new.location = old.location
    for key in SURFACE_KEYS:
        src, dst = surface_input(old, key), surface_input(new, key)
        if key != "normal":
            carry_input(tree, src, dst)
        elif src.is_linked and not (
            impl == "nodes" and _is_geometry_normal(src.links[0].from_socket)
        ):
            tree.links.new(src.links[0].from_socket, dst)
    for key in OPTION_KEYS:
        value = get_option(old, key)
        if key == "ibl":
            value = indirect_light(impl, value)
        set_option(new, key, value)
    for key in TRANSPORT_KEYS:
        carry_input(tree, transport_input(old, key), transport_input(new, key))
    for link in list(shader_output(old).links):
        tree.links.new(shader_output(new), link.to_socket)
    residual = has_residual(old)
    remove_residual(tree, old)
    drivers.remove_drivers(tree, old)
    tree.nodes.remove(old)
    new.name = new.label = NODE_NAME
    link_geometry_normal(tree, new)
    if residual:
        connect_residual(tree, new)
    return new


def use_osl(scene: bpy.types.Scene) -> bool:
    """Turn on Cycles' Open Shading Language for ``scene``, which the OSL shader needs to
    render (without it Cycles renders the material black); returns whether it was off.
    The one place that does it: the implementation switch, conversion, new materials."""
    if scene.cycles.shading_system:
        return False
    scene.cycles.shading_system = True
    return True


def osl_unavailable_reason(scene: bpy.types.Scene) -> str | None:
    """Why the OSL shader cannot render in this scene's settings, or None when it can."""
    engine = scene.render.engine
    if engine != 'CYCLES':
        label = {
            'BLENDER_EEVEE_NEXT': "EEVEE",
            'BLENDER_EEVEE': "EEVEE",
            'BLENDER_WORKBENCH': "Workbench",
        }.get(engine, engine)
        return f"{label} cannot run OSL shaders; they render only in Cycles"
    if not scene.cycles.shading_system:
        return "Open Shading Language is off (Render Properties > Cycles)"
    if scene.cycles.device != 'CPU':
        return "the render device is the GPU; this OSL shader needs Cycles on the CPU"
    return None
