"""The materials the project makes: the model's (either implementation, model_node) and the
Principled BSDF it is compared with (docs/model.md "The comparison with Principled BSDF").

Both can read their surface inputs from the shaded object (Attribute nodes of type Object
reading the custom properties below), so one material serves a whole sphere matrix and the
OSL shader compiles once whatever the grid size.
"""

from __future__ import annotations

import bpy

from . import compat, model_node, owned
from ..core.model import DEFAULT_ALBEDO, Lighting, ModelOptions, perceptual_roughness

# Per-object custom properties read by the materials (the surface inputs).
PROP_ALBEDO = "ctlab_albedo"
PROP_METALLIC = "ctlab_metallic"
PROP_SMOOTHNESS = "ctlab_smoothness"
GENERATED = owned.LEGACY[owned.MATERIAL]  # the tag before blender/owned.py's mark


def _new_material(name: str) -> bpy.types.Material:
    """A new material of ours (blender/owned.py), replacing our earlier one of that name; a
    user's material of that name is kept (ours is then "<name>.001")."""
    old = owned.find(bpy.data.materials, name, owned.MATERIAL)
    if old is not None:
        bpy.data.materials.remove(old)
    mat = owned.new(bpy.data.materials, name, owned.MATERIAL)
    mat[GENERATED] = True
    compat.use_nodes(mat)
    mat.node_tree.nodes.clear()
    return mat


def _surface_values(nt, per_object: bool, albedo, metallic, smoothness, albedo_image=None):
    """Sockets (or constants) for albedo, metallic and smoothness."""
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
    return albedo_out, metallic_out, smooth_out


def _normal_map(nt, image, strength: float = 1.0):
    """A tangent-space normal map (the UV map's tangents, OpenGL convention) through
    Blender's Normal Map node: its Normal output, the same for either implementation and for
    Principled."""
    tex = nt.nodes.new("ShaderNodeTexImage")
    tex.image = image
    if image.colorspace_settings.name != "Non-Color":
        image.colorspace_settings.name = "Non-Color"
    tex.location = (-700, -300)
    nmap = nt.nodes.new("ShaderNodeNormalMap")
    nmap.inputs["Strength"].default_value = strength
    nmap.location = (-450, -300)
    nt.links.new(tex.outputs["Color"], nmap.inputs["Color"])
    return nmap.outputs["Normal"]


def _connect_or_set(nt, value, sock):
    if isinstance(value, bpy.types.NodeSocket):
        nt.links.new(value, sock)
    else:
        sock.default_value = value


def model_material(
    name="Cook-Torrance",
    impl="osl",
    options: ModelOptions | None = None,
    lighting: Lighting | None = None,
    per_object=False,
    albedo=DEFAULT_ALBEDO,
    metallic=0.0,
    smoothness=0.5,
    albedo_image=None,
    normal_map=None,
    normal_strength: float = 1.0,
) -> bpy.types.Material:
    """A material whose surface is the model (``impl``: "osl" or "nodes") emitting the chosen
    view, with constant or per-object surface inputs, an optional albedo texture and
    tangent-space normal map (of ``normal_strength``), and the given options and lighting."""
    mat = _new_material(name)
    mat.cycles.emission_sampling = 'NONE'  # a view, not a light: never sample it as a lamp
    nt = mat.node_tree
    node = model_node.new_node(nt, impl)
    model_node.connect_output(nt, node)
    values = _surface_values(nt, per_object, albedo, metallic, smoothness, albedo_image)
    for key, value in zip(("albedo", "metallic", "smoothness"), values):
        _connect_or_set(nt, value, model_node.surface_input(node, key))
    if normal_map is not None:
        normal = _normal_map(nt, normal_map, normal_strength)
        nt.links.new(normal, model_node.surface_input(node, "normal"))
    model_node.link_geometry_normal(nt, node)
    model_node.set_options(node, options or ModelOptions())
    model_node.set_lighting(node, lighting or Lighting())
    return mat


def principled_material(
    name="Principled Reference",
    per_object=False,
    albedo=DEFAULT_ALBEDO,
    metallic=0.0,
    smoothness=0.5,
    distribution="MULTI_GGX",
    albedo_image=None,
    normal_map=None,
    normal_strength: float = 1.0,
) -> bpy.types.Material:
    """docs/model.md, "The comparison with Principled BSDF": Base Color = albedo, Metallic =
    metallic, Roughness = 1 - smoothness, IOR 1.5, Specular IOR Level 0.5, Multiscatter GGX;
    the normal map through the same Normal Map node as the model's (``_normal_map``)."""
    mat = _new_material(name)
    nt = mat.node_tree
    bsdf = nt.nodes.new("ShaderNodeBsdfPrincipled")
    bsdf.distribution = distribution
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    out.location = (400, 0)
    nt.links.new(bsdf.outputs["BSDF"], out.inputs["Surface"])
    bsdf.inputs["IOR"].default_value = 1.5
    bsdf.inputs["Specular IOR Level"].default_value = 0.5
    albedo_s, metallic_s, smooth_s = _surface_values(
        nt, per_object, albedo, metallic, smoothness, albedo_image
    )
    _connect_or_set(nt, albedo_s, bsdf.inputs["Base Color"])
    _connect_or_set(nt, metallic_s, bsdf.inputs["Metallic"])
    if normal_map is not None:
        nt.links.new(_normal_map(nt, normal_map, normal_strength), bsdf.inputs["Normal"])
        mat.cycles.use_bump_map_correction = False
    if isinstance(smooth_s, bpy.types.NodeSocket):
        invert = nt.nodes.new("ShaderNodeMath")  # roughness = 1 - smoothness
        invert.operation = 'SUBTRACT'
        invert.use_clamp = True
        invert.inputs[0].default_value = 1.0
        nt.links.new(smooth_s, invert.inputs[1])
        nt.links.new(invert.outputs[0], bsdf.inputs["Roughness"])
    else:
        bsdf.inputs["Roughness"].default_value = perceptual_roughness(smooth_s)
    return mat
