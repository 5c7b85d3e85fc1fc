"""The Cook-Torrance materials of the open file as the export sees them (core.export.network
Material): each material's surface values, switches and the objects it is on, and the image
textures wired into albedo, metallic, smoothness and normal, with their colour spaces.

Either implementation (model_node finds the node). What a texture may be (``_texture``): an
Image Texture linked straight into an input, or through the nodes conversion and the Unity
import wire (a ``1 - x`` for a roughness map; a Separate Color's Red, an Alpha output and a
Multiply for Unity's packed map; a Mix (Multiply) by ``_Color``; a Normal Map node in tangent
space; a Mapping node for tiling). Any other node feeding an input is not carried: the
socket's own value is written and a note says so. An image whose file is missing is a
UserError (one line); a packed image is written out from the file's data.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, replace
from pathlib import Path

import bpy

from . import model_node
from ..core.errors import UserError
from ..core.export.network import COLORSPACES, SURFACE_KEYS, Material, Texture
from ..core.export.names import export_names, texture_name, utf8_text


# A packed image without a file name gets its format's extension.
EXTENSIONS = {"PNG": ".png", "JPEG": ".jpg", "OPEN_EXR": ".exr", "HDR": ".hdr", "TIFF": ".tif"}


@dataclass(frozen=True)
class TextureFile:
    """An image to put in the export folder: its file there (``name``), and where its bytes
    come from: a file (``source``) or the .blend's packed data (``data``)."""

    name: str
    source: str = ""
    data: bytes = b""


def _display(path: str) -> str:
    """A path for a message: undecodable bytes (a non-UTF-8 file name) as U+FFFD."""
    return utf8_text(path)


def _library(id_) -> str:
    """The library .blend a linked data-block comes from, as the file names it ("" local)."""
    return utf8_text(id_.library.filepath) if id_.library is not None else ""


def _image_file(image: bpy.types.Image, mat, files: dict) -> str:
    """The image's name inside the export folder (textures/NAME), registered in ``files``,
    which is keyed by the image data-block (a local image and one linked from a library may
    share a name): a bounded ASCII name, unique without case (names.texture_name)."""
    key = image.as_pointer()
    if key in files:
        return files[key]["file"].name
    who = f"image {image.name_full!r} of material {mat.name_full!r}"
    packed = image.packed_file
    path = bpy.path.abspath(image.filepath, library=image.library) if image.filepath else ""
    if image.source != 'FILE' and packed is None:
        raise UserError(
            f"{who} is not a single image file ({image.source.lower()}); the export carries "
            "image files only"
        )
    if packed is None and (not path or not os.path.isfile(path)):
        raise UserError(
            f"{who}: its file is missing ({_display(path) or 'no path'}); find it (File > "
            "External Data > Find Missing Files) or pack it, and save"
        )
    if packed is None and utf8_text(path) != path:
        # The export reads its file by name (OpenImageIO takes UTF-8 names only) and records
        # it as an input: a name of undecodable bytes is refused, never half-read
        raise UserError(
            f"{who}: its file name is not valid UTF-8 ({_display(path)}); rename the file (or "
            "pack the image: File > External Data > Pack Resources), and save"
        )
    stem, ext = os.path.splitext(os.path.basename(path))
    used = {_fold_name(f["file"].name) for f in files.values()}
    name = texture_name(stem or image.name, ext, EXTENSIONS.get(image.file_format, ".png"), used)
    if packed is not None:
        files[key] = {"file": TextureFile(name, data=bytes(packed.data))}
    else:
        files[key] = {"file": TextureFile(name, source=path)}
    return name


def _fold_name(name: str) -> str:
    return name.casefold()


def _colorspace(image: bpy.types.Image) -> str:
    name = image.colorspace_settings.name
    return COLORSPACES.get(name, "srgb_texture" if "sRGB" in name else "")


def _constant(sock) -> bool:
    return not sock.is_linked


def _from(sock):
    """The node and output socket linked into ``sock``."""
    link = sock.links[0]
    return link.from_node, link.from_socket


def _tint(node):
    """A Mix node (colour, Multiply, factor 1) of an input times a constant colour: (the
    linked input, the colour), else None."""
    if node.bl_idname != "ShaderNodeMix" or node.data_type != 'RGBA':
        return None
    if node.blend_type != 'MULTIPLY' or node.clamp_result:
        return None
    ins = {s.identifier: s for s in node.inputs}
    fac, a, b = ins.get("Factor_Float"), ins.get("A_Color"), ins.get("B_Color")
    if fac is None or fac.is_linked or abs(fac.default_value - 1.0) > 1e-6:
        return None
    for linked, const in ((a, b), (b, a)):
        if linked.is_linked and _constant(const):
            return linked, tuple(const.default_value[:3])
    return None


def _scale(node):
    """A Math node multiplying an input by a constant: (the linked input, the constant)."""
    if node.bl_idname != "ShaderNodeMath" or node.operation != 'MULTIPLY' or node.use_clamp:
        return None
    a, b = node.inputs[0], node.inputs[1]
    for linked, const in ((a, b), (b, a)):
        if linked.is_linked and _constant(const):
            return linked, float(const.default_value)
    return None


def _one_minus(node):
    """A Math node 1 - x (Subtract, first value 1): the linked input."""
    if node.bl_idname != "ShaderNodeMath" or node.operation != 'SUBTRACT' or node.use_clamp:
        return None
    first, second = node.inputs[0], node.inputs[1]
    if _constant(first) and abs(first.default_value - 1.0) < 1e-6 and second.is_linked:
        return second
    return None


def _uv(tex_node):
    """The image's UV mapping: (scale, offset) from a Mapping node (Point, no rotation) on
    the UV map (or on nothing: the UV map), ((1, 1), (0, 0)) without one; None when another
    node maps it."""
    vec = tex_node.inputs["Vector"]
    if not vec.is_linked:
        return (1.0, 1.0), (0.0, 0.0)
    node, out = _from(vec)
    if node.bl_idname == "ShaderNodeTexCoord" and out.name == "UV":
        return (1.0, 1.0), (0.0, 0.0)
    if node.bl_idname != "ShaderNodeMapping" or node.vector_type != 'POINT':
        return None
    ins = node.inputs
    if any(s.is_linked for s in ins if s.name != "Vector") or any(ins["Rotation"].default_value):
        return None
    src = ins["Vector"]
    if src.is_linked:
        coords, out = _from(src)
        if coords.bl_idname != "ShaderNodeTexCoord" or out.name != "UV":
            return None
    scale, loc = ins["Scale"].default_value, ins["Location"].default_value
    return (float(scale[0]), float(scale[1])), (float(loc[0]), float(loc[1]))


def _texture(mat, key: str, sock, files: dict, notes: list) -> Texture | None:
    """The texture feeding ``sock``, or None (a value; a note when another node feeds it).
    The shapes read (network.Texture): on the albedo an Image Texture's Color, times a
    constant colour (Mix, Multiply); on metallic and smoothness its Color, its Alpha or the
    Red of a Separate Color of it, then ``1 - x`` and a Multiply by a constant; on the normal
    a tangent-space Normal Map node of it; each image on the UV map, through a Mapping node
    (Point) or not."""
    if not sock.is_linked:
        return None
    fed_by = sock.links[0].from_node
    src, out = _from(sock)
    found = {}
    if key == "normal":
        if src.bl_idname == "ShaderNodeNewGeometry":
            return None  # the geometry's normal: the default
        if src.bl_idname == "ShaderNodeNormalMap" and src.space == 'TANGENT':
            found["strength"] = float(src.inputs["Strength"].default_value)
            color = src.inputs["Color"]
            src, out = _from(color) if color.is_linked else (None, None)
    elif key == "albedo":
        tint = _tint(src)
        if tint is not None:
            found["tint"] = tint[1]
            src, out = _from(tint[0])
    else:
        scaled = _scale(src)
        if scaled is not None:
            found["scale"] = scaled[1]
            src, out = _from(scaled[0])
        inverted = _one_minus(src)
        if inverted is not None:
            found["invert"] = True
            src, out = _from(inverted)
        if src.bl_idname == "ShaderNodeSeparateColor" and src.mode == 'RGB' and out.name == "Red":
            found["channel"] = "r"
            color = src.inputs["Color"]
            src, out = _from(color) if color.is_linked else (None, None)
        elif src.bl_idname == "ShaderNodeTexImage" and out.name == "Alpha":
            found["channel"] = "a"
    uv = _uv(src) if src is not None and src.bl_idname == "ShaderNodeTexImage" else None
    if src is None or src.bl_idname != "ShaderNodeTexImage" or src.image is None or uv is None:
        notes.append(
            f"{mat.name}: {key} is fed by {fed_by.name!r}, which the export cannot carry; the "
            "socket's own value is written"
        )
        return None
    if out.name == "Alpha" and found.get("channel") != "a":
        notes.append(f"{mat.name}: {key} reads an image's Alpha, which the export cannot carry")
        return None
    name = _image_file(src.image, mat, files)
    return Texture(name, _colorspace(src.image), uv_scale=uv[0], uv_offset=uv[1], **found)


def read_material(mat: bpy.types.Material, node, files: dict, notes: list) -> Material:
    textures = {}
    for key in SURFACE_KEYS:
        tex = _texture(mat, key, model_node.surface_input(node, key), files, notes)
        if tex is not None:
            textures[key] = tex
    objects = tuple(
        sorted(
            o.name_full  # a linked object's with its library: "Cube [props.blend]"
            for o in bpy.data.objects
            if any(slot.material == mat for slot in getattr(o, "material_slots", ()))
        )
    )
    return Material(
        name=mat.name,
        albedo=tuple(model_node.surface_input(node, "albedo").default_value[:3]),
        metallic=float(model_node.surface_input(node, "metallic").default_value),
        smoothness=float(model_node.surface_input(node, "smoothness").default_value),
        g_model=model_node.get_option(node, "g_model"),
        diffuse_model=model_node.get_option(node, "diffuse_model"),
        energy=model_node.get_option(node, "energy"),
        units=model_node.get_option(node, "units"),
        textures=textures,
        objects=objects,
        library=_library(mat),
    )


def read_materials(materials=None) -> tuple:
    """(materials, texture files, notes) for the given materials (default: every material
    of the file that uses the model, in the order of (name, library): a local material and
    one linked from a library may share a name; a library whose file is missing is refused,
    since its materials cannot be read). Each material carries its names in the export
    (names.export_names over all of them)."""
    if materials is None:
        from .user_blend import check_libraries

        check_libraries(Path(bpy.data.filepath or "this file"))
        found = sorted(model_node.model_materials(), key=lambda mn: _order(mn[0]))
    else:
        found = [(m, model_node.find(m)) for m in materials if model_node.find(m) is not None]
    files, notes = {}, []
    out = [read_material(mat, node, files, notes) for mat, node in found]
    out = [replace(m, names=n) for m, n in zip(out, export_names(out))]
    return out, [f["file"] for f in files.values()], notes


def _order(mat) -> tuple:
    return (mat.name, _library(mat))
