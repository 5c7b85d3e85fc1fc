"""The Cook-Torrance materials of the open file as the export sees them (core.export.network
Material): each material's surface values, switches and the objects it is on, and the image
textures wired into albedo, metallic, smoothness and normal, with their colour spaces.

Either implementation (model_node finds the node). What a texture may be: an Image Texture
linked straight into an input; on metallic or smoothness also through a ``1 - x`` Math node
(Subtract, first value 1: a roughness map, as conversion wires it); on the normal through a
Normal Map node in tangent space. Any other node feeding an input is not carried: the
socket's own value is written and a note says so. An image whose file is missing is a
UserError (one line); a packed image is written out from the file's data.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import bpy

from . import model_node
from ..core.errors import UserError
from ..core.export.network import COLORSPACES, SURFACE_KEYS, Material, Texture
from ..core.paths import safe_name


# A packed image without a file name gets its format's extension.
EXTENSIONS = {"PNG": ".png", "JPEG": ".jpg", "OPEN_EXR": ".exr", "HDR": ".hdr", "TIFF": ".tif"}


@dataclass(frozen=True)
class TextureFile:
    """An image to put in the export folder: its file there (``name``), and where its bytes
    come from: a file (``source``) or the .blend's packed data (``data``)."""

    name: str
    source: str = ""
    data: bytes = b""


def _image_file(image: bpy.types.Image, mat_name: str, files: dict) -> str:
    """The image's name inside the export folder (textures/NAME), registered in ``files``."""
    for name, f in files.items():
        if f.get("image") == image.name:
            return name
    packed = image.packed_file
    path = bpy.path.abspath(image.filepath, library=image.library) if image.filepath else ""
    ext = os.path.splitext(path)[1] or EXTENSIONS.get(image.file_format, ".png")
    stem = safe_name(os.path.splitext(os.path.basename(path))[0] or image.name, "texture")
    name, i = f"textures/{stem}{ext}", 1
    while name in files:
        i += 1
        name = f"textures/{stem}_{i}{ext}"
    if packed is not None:
        files[name] = {"image": image.name, "file": TextureFile(name, data=bytes(packed.data))}
    elif image.source != 'FILE':
        raise UserError(
            f"image {image.name!r} of material {mat_name!r} is not a single image file "
            f"({image.source.lower()}); the export carries image files only"
        )
    elif not path or not os.path.isfile(path):
        raise UserError(
            f"image {image.name!r} of material {mat_name!r}: its file is missing "
            f"({path or 'no path'}); find it (File > External Data > Find Missing Files) "
            "or pack it, and save"
        )
    else:
        files[name] = {"image": image.name, "file": TextureFile(name, source=path)}
    return name


def _colorspace(image: bpy.types.Image) -> str:
    name = image.colorspace_settings.name
    return COLORSPACES.get(name, "srgb_texture" if "sRGB" in name else "")


def _texture(mat, key: str, sock, files: dict, notes: list) -> Texture | None:
    """The texture feeding ``sock``, or None (a value; a note when another node feeds it)."""
    if not sock.is_linked:
        return None
    src = sock.links[0].from_node
    invert, strength = False, 1.0
    if key == "normal":
        if src.bl_idname == "ShaderNodeNewGeometry":
            return None  # the geometry's normal: the default
        if src.bl_idname == "ShaderNodeNormalMap" and src.space == 'TANGENT':
            strength = float(src.inputs["Strength"].default_value)
            color = src.inputs["Color"]
            src = color.links[0].from_node if color.is_linked else None
    elif (
        key in ("metallic", "smoothness")
        and src.bl_idname == "ShaderNodeMath"
        and src.operation == 'SUBTRACT'
        and not src.inputs[0].is_linked
        and abs(src.inputs[0].default_value - 1.0) < 1e-6
        and src.inputs[1].is_linked
    ):
        invert = True
        src = src.inputs[1].links[0].from_node
    if src is None or src.bl_idname != "ShaderNodeTexImage" or src.image is None:
        notes.append(
            f"{mat.name}: {key} is fed by {sock.links[0].from_node.name!r}, which the export "
            "cannot carry; the socket's own value is written"
        )
        return None
    name = _image_file(src.image, mat.name, files)
    return Texture(name, _colorspace(src.image), invert, strength)


def read_material(mat: bpy.types.Material, node, files: dict, notes: list) -> Material:
    textures = {}
    for key in SURFACE_KEYS:
        tex = _texture(mat, key, model_node.surface_input(node, key), files, notes)
        if tex is not None:
            textures[key] = tex
    objects = tuple(
        sorted(
            o.name
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
    )


def read_materials(materials=None) -> tuple:
    """(materials, texture files, notes) for the given materials (default: every material
    of the file that uses the model, in name order)."""
    if materials is None:
        found = sorted(model_node.model_materials(), key=lambda mn: mn[0].name)
    else:
        found = [(m, model_node.find(m)) for m in materials if model_node.find(m) is not None]
    files, notes = {}, []
    out = [read_material(mat, node, files, notes) for mat, node in found]
    return out, [f["file"] for f in files.values()], notes
