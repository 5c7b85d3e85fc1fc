"""Unity's Standard materials as Cook-Torrance materials (core/unity/standard.py says what a
Standard material means for the model; docs/usage.md "To and from Unity" is the table).

Each material is what the add-on's New Material makes (the default implementation, the
artist's defaults: model_node.set_defaults in the ARTIST context) with its surface wired:

- albedo: the ``_MainTex`` Image Texture, times ``_Color`` (decoded to linear) through a Mix
  node (Multiply) when ``_Color`` is not white, else straight in (the export reads that as
  the albedo texture); ``_Color`` alone without a texture
- metallic: the ``_MetallicGlossMap``'s R (Separate Color), else ``_Metallic``
- smoothness: the metallic-gloss map's (or, with ``_SmoothnessTextureChannel`` 1, the albedo
  map's) Alpha times ``_GlossMapScale`` (a Math node), else the constant
- normal: ``_BumpMap`` (Non-Color) through a tangent-space Normal Map node of Strength =
  ``_BumpScale``. Unity scales the map's XY by it and renormalises; Blender's Strength blends
  the geometric and the mapped normal: the two agree at 0 and 1 only.
- ``_MainTex``'s tiling and offset through one Mapping node (Point: UV * Scale + Location)
  for every map, as Standard reads them all with ``_MainTex_ST``.

Images are loaded with their ``.meta``'s colour space (sRGB or Non-Color; a normal map is
Non-Color) and alpha mode Channel Packed, since an image in Straight alpha is premultiplied by
Cycles and its colour no longer holds the file's values where alpha < 1. A material on no
object gets a fake user, so that it is saved."""

from __future__ import annotations

import bpy

from . import compat, model_node
from ..core.errors import UserError
from ..core.model import ARTIST
from ..core.unity.standard import Surface

SOURCE_PROP = "ctlab_unity_source"  # the .mat a material came from


def _image(path: str, srgb: bool, warnings: list, who: str):
    try:
        image = bpy.data.images.load(path, check_existing=True)
    except RuntimeError as exc:
        warnings.append(f"{who}: Blender cannot read {path} ({str(exc).strip()}); kept without it")
        return None
    image.colorspace_settings.name = "sRGB" if srgb else "Non-Color"
    image.alpha_mode = 'CHANNEL_PACKED'
    return image


def _texture(nt, image, location):
    tex = nt.nodes.new("ShaderNodeTexImage")
    tex.image = image
    tex.location = location
    return tex


def _socket(node, identifier):
    return next(s for s in node.inputs if s.identifier == identifier)


def _output(node, identifier):
    return next(s for s in node.outputs if s.identifier == identifier)


def _is_white(rgb) -> bool:
    return all(abs(c - 1.0) < 1e-7 for c in rgb)


def build_material(surface: Surface, impl: str = "nodes", scene=None) -> tuple:
    """A new Cook-Torrance material from a Standard material's Surface; (material,
    warnings). ``scene``: light it from this scene's Sun and world, as New Material does."""
    warnings = list(surface.warnings)
    who = surface.name
    mat = bpy.data.materials.new(surface.name)
    try:
        compat.use_nodes(mat)
        nt = mat.node_tree
        nt.nodes.clear()
        node = model_node.new_node(nt, impl)
        model_node.connect_output(nt, node)
        model_node.set_defaults(node, ARTIST)
        mat.cycles.emission_sampling = 'NONE'
        _wire(nt, node, surface, warnings, who)
        model_node.link_geometry_normal(nt, node)
    except Exception:
        bpy.data.materials.remove(mat)
        raise
    mat.use_fake_user = True
    mat[SOURCE_PROP] = surface.source
    if scene is not None:
        from . import light_sync

        try:
            light_sync.sync_material(mat, scene)
        except UserError as exc:
            warnings.append(f"{who}: imported, but not lit from the scene: {exc}")
    return mat, warnings


def _wire(nt, node, s: Surface, warnings: list, who: str) -> None:
    albedo_in = model_node.surface_input(node, "albedo")
    metallic_in = model_node.surface_input(node, "metallic")
    smooth_in = model_node.surface_input(node, "smoothness")
    normal_in = model_node.surface_input(node, "normal")
    albedo_in.default_value = tuple(s.albedo) + (1.0,)
    metallic_in.default_value = s.metallic
    smooth_in.default_value = s.smoothness
    textures = []
    albedo_tex = gloss_tex = None
    if s.albedo_map is not None:
        image = _image(s.albedo_map.path, s.albedo_map.srgb, warnings, who)
        if image is not None:
            albedo_tex = _texture(nt, image, (-900, 400))
            textures.append(albedo_tex)
            if _is_white(s.albedo):
                nt.links.new(albedo_tex.outputs["Color"], albedo_in)
            else:
                mix = nt.nodes.new("ShaderNodeMix")
                mix.data_type = 'RGBA'
                mix.blend_type = 'MULTIPLY'
                mix.location = (-550, 400)
                _socket(mix, "Factor_Float").default_value = 1.0
                nt.links.new(albedo_tex.outputs["Color"], _socket(mix, "A_Color"))
                _socket(mix, "B_Color").default_value = tuple(s.albedo) + (1.0,)
                nt.links.new(_output(mix, "Result_Color"), albedo_in)
    if s.metallic_map is not None:
        image = _image(s.metallic_map.path, s.metallic_map.srgb, warnings, who)
        if image is not None:
            gloss_tex = _texture(nt, image, (-900, 50))
            textures.append(gloss_tex)
            split = nt.nodes.new("ShaderNodeSeparateColor")
            split.location = (-550, 100)
            nt.links.new(gloss_tex.outputs["Color"], split.inputs["Color"])
            nt.links.new(split.outputs["Red"], metallic_in)
    alpha_from = {"metallic_map": gloss_tex, "albedo_map": albedo_tex}.get(s.smoothness_from)
    if alpha_from is not None:
        scale = nt.nodes.new("ShaderNodeMath")
        scale.operation = 'MULTIPLY'
        scale.label = "_GlossMapScale"
        scale.location = (-550, -100)
        nt.links.new(alpha_from.outputs["Alpha"], scale.inputs[0])
        scale.inputs[1].default_value = s.gloss_map_scale
        nt.links.new(scale.outputs[0], smooth_in)
    elif s.smoothness_from != "constant":
        # the map was not loaded: Unity's default texture (white, alpha 1) in its place
        smooth_in.default_value = s.gloss_map_scale
    if s.normal_map is not None:
        image = _image(s.normal_map.path, False, warnings, who)
        if image is not None:
            tex = _texture(nt, image, (-900, -300))
            textures.append(tex)
            nmap = nt.nodes.new("ShaderNodeNormalMap")
            nmap.space = 'TANGENT'
            nmap.inputs["Strength"].default_value = s.bump_scale
            nmap.location = (-550, -300)
            nt.links.new(tex.outputs["Color"], nmap.inputs["Color"])
            nt.links.new(nmap.outputs["Normal"], normal_in)
    if textures and (tuple(s.tiling) != (1.0, 1.0) or tuple(s.offset) != (0.0, 0.0)):
        coords = nt.nodes.new("ShaderNodeTexCoord")
        coords.location = (-1400, 0)
        mapping = nt.nodes.new("ShaderNodeMapping")
        mapping.vector_type = 'POINT'
        mapping.location = (-1200, 0)
        mapping.inputs["Scale"].default_value = (s.tiling[0], s.tiling[1], 1.0)
        mapping.inputs["Location"].default_value = (s.offset[0], s.offset[1], 0.0)
        nt.links.new(coords.outputs["UV"], mapping.inputs["Vector"])
        for tex in textures:
            nt.links.new(mapping.outputs["Vector"], tex.inputs["Vector"])
