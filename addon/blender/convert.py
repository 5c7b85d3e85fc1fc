"""Conversion between Principled BSDF and the Cook-Torrance model in a user's material.

docs/model.md, "The comparison with Principled BSDF", both ways: Base Color <-> albedo, Metallic <->
metallic, Roughness <-> 1 - smoothness, Normal <-> normal. Links are kept (an image texture
stays wired; a linked Roughness gets a "1 - x" Math node, which the way back removes again),
values are copied. What the other side cannot express is reported, never silently dropped:
each function returns a list of notes.

Energy: Principled's Multiscatter GGX keeps the light that single scattering loses (Cycles'
albedo scaling, Kulla and Conty 2017); the model's counterpart is energy ``compensated``
(docs/model.md, "energy"), its single-scatter GGX is ``none``. Both ways keep that behaviour
(``ENERGY_OF``): a rough metal converted from the default Principled is not 9% darker.
"""

from __future__ import annotations

import bpy

from . import light_sync, model_node
from ..core.errors import UserError
from ..core.model import ARTIST, OPTION_VALUES

INVERT_TAG = "ctlab_one_minus"  # the Math node: smoothness = 1 - roughness (or back)
SAVED_EMISSION_SAMPLING = "ctlab_saved_emission_sampling"

# Principled's distribution -> the model's energy, and back (the module's docstring)
ENERGY_OF = {'MULTI_GGX': "compensated", 'GGX': "none"}
DISTRIBUTION_OF = {energy: distribution for distribution, energy in ENERGY_OF.items()}

# Principled inputs the model has no counterpart for: (input, label, its neutral value).
# An input that is linked, or whose value differs from the neutral one, is reported.
PRINCIPLED_UNMAPPED = (
    ("Subsurface Weight", "subsurface", 0.0),
    ("Transmission Weight", "transmission", 0.0),
    ("Coat Weight", "coat", 0.0),
    ("Sheen Weight", "sheen", 0.0),
    ("Emission Strength", "emission", 0.0),
    ("Alpha", "alpha", 1.0),
    ("Anisotropic", "anisotropy", 0.0),
    ("Thin Film Thickness", "thin film", 0.0),
    ("Specular Tint", "specular tint", (1.0, 1.0, 1.0, 1.0)),
    ("IOR", "IOR (the model's dielectric F0 is 0.04, IOR 1.5)", 1.5),
    ("Specular IOR Level", "specular IOR level", 0.5),
)


def _differs(value, neutral) -> bool:
    if isinstance(neutral, tuple):
        return any(abs(a - b) > 1e-6 for a, b in zip(value, neutral))
    return abs(value - neutral) > 1e-6


def surface_principled(mat: bpy.types.Material) -> bpy.types.Node | None:
    """The Principled BSDF wired to the material's active output Surface, if any."""
    if mat is None or mat.node_tree is None:
        return None
    out = mat.node_tree.get_output_node('ALL') or mat.node_tree.get_output_node('CYCLES')
    if out is None or not out.inputs["Surface"].is_linked:
        return None
    node = out.inputs["Surface"].links[0].from_node
    return node if node.bl_idname == "ShaderNodeBsdfPrincipled" else None


def _one_minus(tree, source: bpy.types.NodeSocket, location, label) -> bpy.types.NodeSocket:
    node = tree.nodes.new("ShaderNodeMath")
    node.operation = 'SUBTRACT'
    node.use_clamp = True
    node.inputs[0].default_value = 1.0
    node.label = label
    node[INVERT_TAG] = True
    node.location = location
    tree.links.new(source, node.inputs[1])
    return node.outputs[0]


def _invert_link(tree, dst: bpy.types.NodeSocket, src: bpy.types.NodeSocket, label: str) -> None:
    """Wire ``dst`` = 1 - ``src``'s value: undo our own 1 - x node, else add one."""
    source = src.links[0].from_socket
    node = source.node
    if node.get(INVERT_TAG) and node.inputs[1].is_linked:
        tree.links.new(node.inputs[1].links[0].from_socket, dst)
        if len(node.outputs[0].links) <= 1:
            tree.nodes.remove(node)
        return
    location = (dst.node.location.x - 200, dst.node.location.y - 200)
    tree.links.new(_one_minus(tree, source, location, label), dst)


def principled_to_model(
    mat: bpy.types.Material,
    scene: bpy.types.Scene,
    impl: str,
    light_transport: str | None = None,
) -> list:
    """Replace the material's Principled BSDF by the Cook-Torrance node; returns notes on
    what could not be mapped. Raises UserError when the surface is not a Principled BSDF.
    ``light_transport`` None: an artist's material's default (core.model.rules: path traced
    as Principled was, the scene transport)."""
    bsdf = surface_principled(mat)
    if bsdf is None:
        raise UserError(
            f"material {mat.name!r}: its surface is not a Principled BSDF; nothing to convert"
        )
    tree = mat.node_tree
    if impl == "osl":  # the OSL shader renders black without it: the file renders as saved
        model_node.use_osl(scene)
    notes = []
    for name, label, neutral in PRINCIPLED_UNMAPPED:
        sock = bsdf.inputs.get(name)
        if sock is None:
            continue
        if (
            name == "Emission Strength"
            and not _differs(
                tuple(bsdf.inputs["Emission Color"].default_value), (0.0, 0.0, 0.0, 1.0)
            )
            and not bsdf.inputs["Emission Color"].is_linked
        ):
            continue
        if sock.is_linked or _differs(
            tuple(sock.default_value) if isinstance(neutral, tuple) else sock.default_value, neutral
        ):
            notes.append(label)
    energy = ENERGY_OF.get(bsdf.distribution)
    if energy is None:
        notes.append(f"distribution {bsdf.distribution}")
    node = model_node.new_node(tree, impl)
    node.location = bsdf.location
    model_node.carry_input(
        tree, bsdf.inputs["Base Color"], model_node.surface_input(node, "albedo")
    )
    model_node.carry_input(
        tree, bsdf.inputs["Metallic"], model_node.surface_input(node, "metallic")
    )
    rough, smooth = bsdf.inputs["Roughness"], model_node.surface_input(node, "smoothness")
    if rough.is_linked:
        _invert_link(tree, smooth, rough, "Smoothness = 1 - Roughness")
    else:
        smooth.default_value = 1.0 - rough.default_value
    if bsdf.inputs["Normal"].is_linked:
        tree.links.new(
            bsdf.inputs["Normal"].links[0].from_socket, model_node.surface_input(node, "normal")
        )
    for link in list(bsdf.outputs["BSDF"].links):
        tree.links.new(model_node.shader_output(node), link.to_socket)
    tree.nodes.remove(bsdf)
    model_node.link_geometry_normal(tree, node)
    model_node.set_defaults(node, ARTIST, light_transport=light_transport)
    model_node.set_option(node, "energy", energy or "none")
    # the model emits its view: never sample it as a light (restored on the way back)
    mat[SAVED_EMISSION_SAMPLING] = mat.cycles.emission_sampling
    mat.cycles.emission_sampling = 'NONE'
    light_sync.sync_material(mat, scene)
    return notes


def model_to_principled(mat: bpy.types.Material) -> list:
    """Replace the material's Cook-Torrance node by a Principled BSDF (IOR 1.5; Multiscatter
    GGX for energy compensated, GGX for none: ``DISTRIBUTION_OF``); returns notes on the
    model settings Principled has no counterpart for."""
    node = model_node.find(mat)
    if node is None:
        raise UserError(
            f"material {mat.name!r} does not use the Cook-Torrance model; nothing to convert"
        )
    tree = mat.node_tree
    notes = [
        f"{key.replace('_', ' ')} {model_node.get_option(node, key)}"
        for key in ("view", "g_model", "diffuse_model", "units")
        if model_node.get_option(node, key) != OPTION_VALUES[key][0]
    ]
    bsdf = tree.nodes.new("ShaderNodeBsdfPrincipled")
    bsdf.location = node.location
    bsdf.distribution = DISTRIBUTION_OF[model_node.get_option(node, "energy")]
    model_node.carry_input(
        tree, model_node.surface_input(node, "albedo"), bsdf.inputs["Base Color"]
    )
    model_node.carry_input(
        tree, model_node.surface_input(node, "metallic"), bsdf.inputs["Metallic"]
    )
    smooth = model_node.surface_input(node, "smoothness")
    if smooth.is_linked:
        _invert_link(tree, bsdf.inputs["Roughness"], smooth, "Roughness = 1 - Smoothness")
    else:
        bsdf.inputs["Roughness"].default_value = 1.0 - smooth.default_value
    normal = model_node.surface_input(node, "normal")
    if normal.is_linked:
        source = normal.links[0].from_socket
        if source.node.bl_idname == "ShaderNodeNewGeometry":
            if all(len(o.links) <= 1 for o in source.node.outputs):
                tree.nodes.remove(source.node)  # ours: the OSL node's geometry normal
        else:
            tree.links.new(source, bsdf.inputs["Normal"])
    for link in list(model_node.shader_output(node).links):
        tree.links.new(bsdf.outputs["BSDF"], link.to_socket)
    model_node.remove_drivers(tree, node)
    model_node.remove_residual(tree, node)
    tree.nodes.remove(node)
    mat.cycles.emission_sampling = mat.pop(SAVED_EMISSION_SAMPLING, 'AUTO')
    return notes
