"""The model as glTF 2.0 (``ctlab export --format gltf``): metallic-roughness parameters of
glTF's core material (docs/model.md "The model outside Blender"), metallic and roughness maps
packed into one image as glTF wants them, and what glTF cannot carry in extras."""

from __future__ import annotations

import json

from .names import export_names, utf8_text
from .network import DIFFUSE_SCALE, Material, not_carried

TRANSFORM = "KHR_texture_transform"  # a texture's UV mapping (Khronos' ratified extension)


def metallic_roughness_name(mat: Material, materials=None) -> str | None:
    """The glTF metallic-roughness image a material needs (textures/NAME), or None: glTF
    packs roughness in G and metallic in B of one image (maps.py
    ``metallic_roughness_pixels``).
    Its name is unique among the materials exported with it (``names.export_names``): from
    ``materials`` when given (``mat`` one of them), else the names read with the material
    (``mat.names``, blender/material_export.py), else its own alone."""
    if materials is not None:
        materials = list(materials)
        for other, names in zip(materials, export_names(materials)):
            if other is mat:
                return names.metallic_roughness
    if mat.names is not None:
        return mat.names.metallic_roughness
    return export_names([mat])[0].metallic_roughness


def _f7(x) -> float:
    """A float32 value as its 7 significant digits (0.8, not 0.800000011920929)."""
    return float(f"{float(x):.7g}")


def gltf_material(mat: Material, texture_index, packed=None) -> dict:
    """glTF's core material for the model's values: baseColorFactor = albedo, metallicFactor
    = metallic, roughnessFactor = 1 - smoothness (glTF's roughness is perceptual, squared to
    GGX's alpha like the model's pr); the albedo, normal and metallic-roughness textures (a
    factor is 1 where its texture holds the values). ``texture_index(file)`` gives a
    texture's index in the file; ``packed`` the material's metallic-roughness image
    (``metallic_roughness_name``). The switches glTF cannot carry go to extras."""
    pbr = {
        "baseColorFactor": [_f7(c) for c in mat.albedo[:3]] + [1.0],
        "metallicFactor": _f7(mat.metallic),
        "roughnessFactor": _f7(1.0 - float(mat.smoothness)),
    }
    out = {"name": utf8_text(mat.name), "pbrMetallicRoughness": pbr}
    if "albedo" in mat.textures:
        tex = mat.textures["albedo"]
        pbr["baseColorFactor"] = [_f7(c) for c in (tex.tint or (1.0, 1.0, 1.0))[:3]] + [1.0]
        pbr["baseColorTexture"] = _info(texture_index(tex.file), tex)
    if packed is None:
        packed = metallic_roughness_name(mat)
    if packed is not None:
        first = mat.textures.get("metallic") or mat.textures.get("smoothness")
        pbr["metallicRoughnessTexture"] = _info(texture_index(packed), first)
        if "metallic" in mat.textures:
            pbr["metallicFactor"] = 1.0
        if "smoothness" in mat.textures:
            pbr["roughnessFactor"] = 1.0
    if "normal" in mat.textures:
        tex = mat.textures["normal"]
        out["normalTexture"] = dict(_info(texture_index(tex.file), tex), scale=_f7(tex.strength))
    out["extras"] = {
        "cook_torrance_lab": {
            "g_model": mat.g_model,
            "diffuse_model": mat.diffuse_model,
            "energy": mat.energy,
            "units": mat.units,
            "albedo": [_f7(c) for c in mat.albedo[:3]],
            "smoothness": _f7(mat.smoothness),
            "not_carried": gltf_not_carried(mat),
        }
    }
    if mat.library:
        out["extras"]["cook_torrance_lab"]["library"] = utf8_text(mat.library)
    return out


def gltf_not_carried(mat: Material) -> list:
    """What glTF's core material (GGX, height-correlated Smith, Schlick F, Lambert diffuse,
    F0 0.04 with a (1 - F) weighted diffuse) leaves out of this material: always the model's
    diffuse scale (docs/model.md: diffColor = albedo 0.96 (1 - metallic), Unity's constant
    energy split, where glTF weights its Lambert by 1 - F), so no material is exact in glTF."""
    out = not_carried(mat)
    if mat.diffuse_model != "lambert":
        out.append("Burley (Disney) diffuse (glTF's diffuse is Lambert)")
    out.append(f"the diffuse scale {DIFFUSE_SCALE:g} (glTF weights its Lambert diffuse by 1 - F)")
    maps = [mat.textures[k] for k in ("metallic", "smoothness") if k in mat.textures]
    if len({(t.uv_scale, t.uv_offset) for t in maps}) > 1:
        out.append("the smoothness map's UV mapping (packed with the metallic map, read with its)")
    return out


def _info(index: int, tex) -> dict:
    """A textureInfo: the texture's index, and its UV mapping as KHR_texture_transform.
    Blender's UV has v up from the image's bottom, glTF's down from its top (v_gltf = 1 -
    v_blender), so Blender's UV * s + o is glTF's UV * s + (o_u, 1 - s_v - o_v)."""
    info = {"index": index}
    if tex is not None and tex.uv_mapped:
        (su, sv), (ou, ov) = tex.uv_scale, tex.uv_offset
        info["extensions"] = {
            TRANSFORM: {"offset": [_f7(ou), _f7(1.0 - sv - ov)], "scale": [_f7(su), _f7(sv)]}
        }
    return info


def gltf_document(materials: list) -> dict:
    """A minimal glTF 2.0 file holding the materials (no meshes); their packed images named
    all at once (``names.export_names``)."""
    materials = list(materials)
    images, textures, index = [], [], {}

    def texture_index(file: str) -> int:
        if file not in index:
            images.append({"uri": file})
            textures.append({"source": len(images) - 1})
            index[file] = len(textures) - 1
        return index[file]

    doc = {
        "asset": {"version": "2.0", "generator": "Cook-Torrance Lab (ctlab export)"},
        "materials": [
            gltf_material(m, texture_index, n.metallic_roughness)
            for m, n in zip(materials, export_names(materials))
        ],
    }
    if images:
        doc["images"], doc["textures"] = images, textures
    if any(TRANSFORM in json.dumps(m) for m in doc["materials"]):
        doc["extensionsUsed"] = [TRANSFORM]
    return doc
