"""The model's node in a material, behind one interface whichever implementation carries it:
the OSL script node (osl/cook_torrance.osl) or the node group (node_groups/cook_torrance.toml).

Both name their key-light and world inputs alike (light_sync drives them); their surface
inputs and switches differ in form only (OSL: string parameters; the group: integer inputs),
which ``SURFACE_INPUTS``, ``get_option`` and ``set_option`` translate. A material "uses the
model" when ``find`` returns a node.
"""

from __future__ import annotations

import bpy

from . import osl_shader
from .errors import UserError
from .params import DIFFUSE_MODELS, G_MODELS, IBL_MODES, UNITS, VIEWS

IMPLEMENTATIONS = ("osl", "nodes")
IMPLEMENTATION_LABELS = {"osl": "OSL Shader", "nodes": "Node Group"}
NODE_NAME = "Cook-Torrance"

# key: (OSL parameter, node-group input)
SURFACE_INPUTS = {"albedo": ("albedo", "Albedo"), "metallic": ("metallic", "Metallic"),
                  "smoothness": ("smoothness", "Smoothness"),
                  "normal": ("shading_normal", "Normal")}
# The switches and the view: key -> allowed values (the first is the default).
OPTIONS = {"view": VIEWS, "g_model": G_MODELS, "diffuse_model": DIFFUSE_MODELS,
           "units": UNITS, "ibl": IBL_MODES}
# The node group's integer inputs: 0 selects the first value, 1 the second.
_GROUP_SWITCHES = {"g_model": "G Smith", "diffuse_model": "Diffuse Lambert",
                   "units": "Units Unity"}
_GROUP_IBL = ("split_sum", "unity")          # IBL Unity = 0, 1 (the group has no reference)


def implementation(node: bpy.types.Node) -> str | None:
    if node.bl_idname == "ShaderNodeScript":
        script = node.script
        if script is not None and script.name.startswith(osl_shader.TEXT_NAME):
            return "osl"
    elif node.bl_idname == "ShaderNodeGroup":
        from .node_group import TAG
        if node.node_tree is not None and node.node_tree.get(TAG):
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


def surface_input(node: bpy.types.Node, key: str) -> bpy.types.NodeSocket:
    osl_name, group_name = SURFACE_INPUTS[key]
    if implementation(node) == "osl":
        return osl_shader.socket(node, osl_name)
    return node.inputs[group_name]


def shader_output(node: bpy.types.Node) -> bpy.types.NodeSocket:
    if implementation(node) == "osl":
        return osl_shader.socket(node, "BSDF", output=True)
    return node.outputs["Emission"]


def get_option(node: bpy.types.Node, key: str) -> str:
    if implementation(node) == "osl":
        value = osl_shader.socket(node, key).default_value
        return value if value in OPTIONS[key] else OPTIONS[key][0]
    if key == "view":
        index = int(node.inputs["View"].default_value)
        return VIEWS[min(max(index, 0), len(VIEWS) - 1)]
    if key == "ibl":
        return _GROUP_IBL[int(bool(node.inputs["IBL Unity"].default_value))]
    return OPTIONS[key][int(bool(node.inputs[_GROUP_SWITCHES[key]].default_value))]


def set_option(node: bpy.types.Node, key: str, value: str) -> None:
    """Set a switch or the view; an unknown value, or the reference IBL on the node group,
    is a UserError that says what to choose."""
    allowed = OPTIONS[key]
    if value not in allowed:
        raise UserError(f"unknown {key.replace('_', ' ')} {value!r}; choose one of: "
                        f"{', '.join(allowed)}")
    if implementation(node) == "osl":
        osl_shader.socket(node, key).default_value = value
    elif key == "view":
        node.inputs["View"].default_value = VIEWS.index(value)
    elif key == "ibl":
        if value not in _GROUP_IBL:
            raise UserError("the node group has no reference (Monte Carlo) indirect light; "
                            "choose split_sum or unity, or switch to the OSL implementation")
        node.inputs["IBL Unity"].default_value = _GROUP_IBL.index(value)
    else:
        node.inputs[_GROUP_SWITCHES[key]].default_value = allowed.index(value)


def carry_input(tree: bpy.types.NodeTree, src: bpy.types.NodeSocket,
                dst: bpy.types.NodeSocket) -> None:
    """Give ``dst`` what feeds ``src``: its link, else its value."""
    if src.is_linked:
        tree.links.new(src.links[0].from_socket, dst)
    else:
        dst.default_value = src.default_value


def new_node(tree: bpy.types.NodeTree, impl: str) -> bpy.types.Node:
    """A new Cook-Torrance node of the given implementation in ``tree`` (unlinked)."""
    if impl == "osl":
        node = tree.nodes.new("ShaderNodeScript")
        osl_shader.compile_script_node(node)
    elif impl == "nodes":
        from .node_group import ensure_group
        node = tree.nodes.new("ShaderNodeGroup")
        node.node_tree = ensure_group()
        node.width = 220
    else:
        raise UserError(f"unknown implementation {impl!r}; choose one of: "
                        f"{', '.join(IMPLEMENTATIONS)}")
    node.name = node.label = NODE_NAME
    return node


def link_geometry_normal(tree: bpy.types.NodeTree, node: bpy.types.Node) -> None:
    """The OSL shader reads its normal from a socket: feed it the geometry's when unlinked
    (the node group falls back to the geometry normal by itself)."""
    sock = surface_input(node, "normal")
    if implementation(node) == "osl" and not sock.is_linked:
        geometry = tree.nodes.new("ShaderNodeNewGeometry")
        geometry.location = (node.location.x - 250, node.location.y - 350)
        tree.links.new(geometry.outputs["Normal"], sock)


def _is_geometry_normal(sock: bpy.types.NodeSocket) -> bool:
    return sock.bl_idname.startswith("NodeSocketVector") and \
        sock.node.bl_idname == "ShaderNodeNewGeometry" and sock.name == "Normal"


def replace_node(tree: bpy.types.NodeTree, old: bpy.types.Node, impl: str) -> bpy.types.Node:
    """Replace the model node ``old`` by one of implementation ``impl``, keeping every link and
    value of the surface inputs, the options and the output links. The reference IBL becomes
    split_sum on the node group. Drivers on ``old`` are removed (light_sync adds them again)."""
    from . import light_sync
    new = new_node(tree, impl)
    new.location = old.location
    for key in SURFACE_INPUTS:
        src, dst = surface_input(old, key), surface_input(new, key)
        if key != "normal":
            carry_input(tree, src, dst)
        elif src.is_linked and not (impl == "nodes" and
                                    _is_geometry_normal(src.links[0].from_socket)):
            tree.links.new(src.links[0].from_socket, dst)
    for key in OPTIONS:
        value = get_option(old, key)
        if key == "ibl" and impl == "nodes" and value == "reference":
            value = "split_sum"
        set_option(new, key, value)
    for link in list(shader_output(old).links):
        tree.links.new(shader_output(new), link.to_socket)
    light_sync.remove_drivers(tree, old)
    tree.nodes.remove(old)
    new.name = new.label = NODE_NAME
    link_geometry_normal(tree, new)
    return new


def osl_unavailable_reason(scene: bpy.types.Scene) -> str | None:
    """Why the OSL shader cannot render in this scene's settings, or None when it can."""
    engine = scene.render.engine
    if engine != 'CYCLES':
        label = {'BLENDER_EEVEE_NEXT': "EEVEE", 'BLENDER_EEVEE': "EEVEE",
                 'BLENDER_WORKBENCH': "Workbench"}.get(engine, engine)
        return f"{label} cannot run OSL shaders; they render only in Cycles"
    if not scene.cycles.shading_system:
        return "Open Shading Language is off (Render Properties > Cycles)"
    if scene.cycles.device != 'CPU':
        return "the render device is the GPU; this OSL shader needs Cycles on the CPU"
    return None
