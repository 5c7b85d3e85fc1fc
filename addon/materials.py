"""The materials of the project: Cook-Torrance (OSL or the node group) and the Principled BSDF
reference.

Both can read their surface inputs from the shaded object (Attribute nodes of type Object
reading the custom properties below), so one material serves a whole sphere matrix and the
OSL shader compiles once whatever the grid size.
"""

from __future__ import annotations

import bpy

from . import compat, osl_shader
from .params import DEFAULT_ALBEDO, ModelOptions, perceptual_roughness

# Per-object custom properties read by the materials (SPEC inputs).
PROP_ALBEDO = "ctlab_albedo"
PROP_METALLIC = "ctlab_metallic"
PROP_SMOOTHNESS = "ctlab_smoothness"


class Lighting:
    """What the OSL shader must know of the scene's lights (it cannot read other objects)."""

    def __init__(self, sun_to_light=(0.0, 0.0, 1.0), sun_irradiance=(0.0, 0.0, 0.0),
                 hdri="", hdri_strength=1.0, hdri_rotation=0.0, env_tables=None, ibl_bake=""):
        self.sun_to_light = tuple(sun_to_light)
        self.sun_irradiance = tuple(sun_irradiance)
        self.hdri = str(hdri)
        self.hdri_strength = float(hdri_strength)
        self.hdri_rotation = float(hdri_rotation)      # radians, as the Mapping node's Z
        self.env_tables = env_tables or {}      # reference IBL: importance tables
        self.ibl_bake = str(ibl_bake)           # split_sum / unity IBL: the bake folder


def _new_material(name: str) -> bpy.types.Material:
    old = bpy.data.materials.get(name)
    if old is not None and old.get("ctlab_generated"):
        bpy.data.materials.remove(old)
    mat = bpy.data.materials.new(name)
    mat["ctlab_generated"] = True
    compat.use_nodes(mat)
    mat.node_tree.nodes.clear()
    return mat


def _surface_inputs(nt, per_object: bool, albedo, metallic, smoothness, albedo_image=None):
    """Sockets (or constants) for albedo, metallic and smoothness, and a shading normal socket."""
    nodes = nt.nodes
    if per_object:
        def attr(name, x):
            node = nodes.new("ShaderNodeAttribute")
            node.attribute_type = 'OBJECT'
            node.attribute_name = name
            node.location = (-700, x)
            return node
        albedo_out = attr(PROP_ALBEDO, 300).outputs["Color"]
        metallic_out = attr(PROP_METALLIC, 100).outputs["Fac"]
        smooth_out = attr(PROP_SMOOTHNESS, -100).outputs["Fac"]
    else:
        albedo_out = tuple(albedo) + (1.0,) if len(albedo) == 3 else tuple(albedo)
        metallic_out, smooth_out = float(metallic), float(smoothness)
    if albedo_image is not None:
        tex = nodes.new("ShaderNodeTexImage")
        tex.image = albedo_image
        tex.location = (-700, 500)
        albedo_out = tex.outputs["Color"]
    geometry = nodes.new("ShaderNodeNewGeometry")
    geometry.location = (-700, -300)
    return albedo_out, metallic_out, smooth_out, geometry.outputs["Normal"]


def _connect_or_set(nt, value, sock):
    if isinstance(value, bpy.types.NodeSocket):
        nt.links.new(value, sock)
    else:
        sock.default_value = value


def cook_torrance_material(name="Cook-Torrance", options: ModelOptions | None = None,
                           lighting: Lighting | None = None, per_object=False,
                           albedo=DEFAULT_ALBEDO, metallic=0.0, smoothness=0.5,
                           albedo_image=None, normal_map=None) -> bpy.types.Material:
    """A material whose surface is the Cook-Torrance OSL shader (emitting the chosen view)."""
    options = options or ModelOptions()
    lighting = lighting or Lighting()
    mat = _new_material(name)
    mat.cycles.emission_sampling = 'NONE'     # a view, not a light: never sample it as a lamp
    nt = mat.node_tree
    script = nt.nodes.new("ShaderNodeScript")
    script.name = script.label = "Cook-Torrance"
    osl_shader.compile_script_node(script)
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    out.location = (400, 0)
    out.target = 'CYCLES'
    nt.links.new(osl_shader.socket(script, "BSDF", output=True), out.inputs["Surface"])

    albedo_s, metallic_s, smooth_s, normal_s = _surface_inputs(
        nt, per_object, albedo, metallic, smoothness, albedo_image)
    inp = lambda ident: osl_shader.socket(script, ident)  # noqa: E731
    _connect_or_set(nt, albedo_s, inp("albedo"))
    _connect_or_set(nt, metallic_s, inp("metallic"))
    _connect_or_set(nt, smooth_s, inp("smoothness"))
    if normal_map is not None:
        tex = nt.nodes.new("ShaderNodeTexImage")
        tex.image = normal_map
        tex.image.colorspace_settings.name = "Non-Color"
        nmap = nt.nodes.new("ShaderNodeNormalMap")
        nt.links.new(tex.outputs["Color"], nmap.inputs["Color"])
        normal_s = nmap.outputs["Normal"]
    nt.links.new(normal_s, inp("shading_normal"))
    set_options(mat, options)
    set_lighting(mat, lighting)
    return mat


def script_node(mat: bpy.types.Material) -> bpy.types.ShaderNodeScript:
    return next(n for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeScript")


def set_options(mat: bpy.types.Material, options: ModelOptions) -> None:
    from . import model_node
    node = script_node(mat)
    sock = lambda ident: osl_shader.socket(node, ident)  # noqa: E731
    for key in model_node.OPTIONS:
        model_node.set_option(node, key, getattr(options, key))
    sock("env_samples").default_value = options.env_samples
    sock("env_visibility").default_value = options.env_visibility
    sock("sun_shadow").default_value = options.sun_shadow
    sock("seed").default_value = options.seed


def set_lighting(mat: bpy.types.Material, lighting: Lighting) -> None:
    node = script_node(mat)
    sock = lambda ident: osl_shader.socket(node, ident)  # noqa: E731
    sock("sun_to_light").default_value = lighting.sun_to_light
    sock("sun_irradiance").default_value = tuple(lighting.sun_irradiance) + (1.0,)
    sock("hdri_strength").default_value = lighting.hdri_strength
    sock("hdri_rotation").default_value = lighting.hdri_rotation
    tables = lighting.env_tables
    sock("env_marginal").default_value = tables.get("marginal", "")
    sock("env_conditional").default_value = tables.get("conditional", "")
    sock("env_pdf_table").default_value = tables.get("pdf", "")
    osl_shader.set_environment(node, lighting.hdri, lighting.ibl_bake)


def node_group_material(name="Cook-Torrance (nodes)", options: ModelOptions | None = None,
                        lighting: Lighting | None = None, per_object=False,
                        albedo=DEFAULT_ALBEDO, metallic=0.0, smoothness=0.5,
                        albedo_image=None) -> bpy.types.Material:
    """A material whose surface is the Cook-Torrance node group (node_groups/), emitting the
    chosen view; works in Cycles (SVM or OSL) and EEVEE."""
    from . import node_group
    options = options or ModelOptions()
    lighting = lighting or Lighting()
    group = node_group.ensure_group()
    mat = _new_material(name)
    nt = mat.node_tree
    node = nt.nodes.new("ShaderNodeGroup")
    node.node_tree = group
    node.name = node.label = "Cook-Torrance"
    node.width = 220
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    out.location = (400, 0)
    nt.links.new(node.outputs["Emission"], out.inputs["Surface"])
    albedo_s, metallic_s, smooth_s, _ = _surface_inputs(
        nt, per_object, albedo, metallic, smoothness, albedo_image)
    _connect_or_set(nt, albedo_s, node.inputs["Albedo"])
    _connect_or_set(nt, metallic_s, node.inputs["Metallic"])
    _connect_or_set(nt, smooth_s, node.inputs["Smoothness"])
    set_group_options(node, options)
    set_group_lighting(node, lighting)
    return mat


def group_node(mat: bpy.types.Material) -> bpy.types.ShaderNodeGroup:
    from .node_group import TAG
    return next(n for n in mat.node_tree.nodes
                if n.bl_idname == "ShaderNodeGroup" and n.node_tree and n.node_tree.get(TAG))


def set_group_options(node: bpy.types.ShaderNodeGroup, options: ModelOptions) -> None:
    from . import model_node
    from .node_group import require_baked_ibl
    require_baked_ibl(options.ibl)
    for key in model_node.OPTIONS:
        model_node.set_option(node, key, getattr(options, key))


def set_group_lighting(node: bpy.types.ShaderNodeGroup, lighting: Lighting) -> None:
    from . import node_group
    node.inputs["Sun Direction"].default_value = lighting.sun_to_light
    node.inputs["Sun Irradiance"].default_value = tuple(lighting.sun_irradiance) + (1.0,)
    node.inputs["HDRI Strength"].default_value = lighting.hdri_strength
    node.inputs["HDRI Rotation"].default_value = lighting.hdri_rotation
    if lighting.ibl_bake:
        node_group.set_bake(node.node_tree, lighting.ibl_bake)


def principled_material(name="Principled Reference", per_object=False, albedo=DEFAULT_ALBEDO,
                        metallic=0.0, smoothness=0.5, distribution="MULTI_GGX",
                        albedo_image=None) -> bpy.types.Material:
    """SPEC "Principled BSDF reference mapping": Base Color = albedo, Metallic = metallic,
    Roughness = 1 - smoothness, IOR 1.5, Specular IOR Level 0.5, Multiscatter GGX."""
    mat = _new_material(name)
    nt = mat.node_tree
    bsdf = nt.nodes.new("ShaderNodeBsdfPrincipled")
    bsdf.distribution = distribution
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    out.location = (400, 0)
    nt.links.new(bsdf.outputs["BSDF"], out.inputs["Surface"])
    bsdf.inputs["IOR"].default_value = 1.5
    bsdf.inputs["Specular IOR Level"].default_value = 0.5
    albedo_s, metallic_s, smooth_s, _ = _surface_inputs(
        nt, per_object, albedo, metallic, smoothness, albedo_image)
    _connect_or_set(nt, albedo_s, bsdf.inputs["Base Color"])
    _connect_or_set(nt, metallic_s, bsdf.inputs["Metallic"])
    if isinstance(smooth_s, bpy.types.NodeSocket):
        invert = nt.nodes.new("ShaderNodeMath")       # roughness = 1 - smoothness
        invert.operation = 'SUBTRACT'
        invert.use_clamp = True
        invert.inputs[0].default_value = 1.0
        nt.links.new(smooth_s, invert.inputs[1])
        nt.links.new(invert.outputs[0], bsdf.inputs["Roughness"])
    else:
        bsdf.inputs["Roughness"].default_value = perceptual_roughness(smooth_s)
    return mat
