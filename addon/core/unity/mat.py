"""Writing Unity's material files: a Cook-Torrance material of the export
(``core.export.network.Material``) as a ``.mat`` of Unity's built-in Standard shader,
metallic workflow, with a ``.meta`` per file (a guid derived from the file's name: the same
on every run), the textures' ``.meta`` files (a normal map imported as a normal map, a data
map as not sRGB) and the packed metallic-gloss map (R = metallic, A = smoothness). The one
entry is ``unity_outputs``; docs/usage.md, "To and from Unity", is the mapping.

Colour: Unity serialises a colour as its inspector shows it, sRGB-encoded, and in a project
of Linear colour space decodes it before shading; the model's albedo is linear, so ``_Color``
is its sRGB encoding (``standard.linear_to_srgb``). In a Gamma project the look does not match
(COLOUR_SPACE_NOTE).

The ``.mat`` is Unity 2019/2020's text (Material serializedVersion 6, the flat property
list, the keywords as one string), which every later Unity reads and upgrades; text made
from a template, read back by ``read.py`` (PyYAML)."""

from __future__ import annotations

import hashlib
import re

from ..export.names import TEXTURES, export_names, file_stem, fmt_float, utf8_text
from ..export.network import Material
from ..export.maps import metallic_gloss_pixels, texture_values
from .read import BUILTIN_GUID, STANDARD, TEXTURE_FILE_ID
from .standard import linear_to_srgb

COLOUR_SPACE_NOTE = (
    "Unity: set the project's Color Space to Linear (Project Settings > Player > Other "
    "Settings) for the materials to look as in Blender"
)
PACKED_SUFFIX = "_metallic_gloss.png"
PNG_RGBA = "png_rgba"  # the tag of a packed image to write: (PNG_RGBA, float32 h x w x 4)
MATERIAL_FILE_ID = 2100000

# Standard's properties as Unity writes a new material, in Unity's (sorted) order
_TEX_ENVS = (
    "_BumpMap",
    "_DetailAlbedoMap",
    "_DetailMask",
    "_DetailNormalMap",
    "_EmissionMap",
    "_MainTex",
    "_MetallicGlossMap",
    "_OcclusionMap",
    "_ParallaxMap",
)
_FLOATS = {
    "_BumpScale": 1.0,
    "_Cutoff": 0.5,
    "_DetailNormalMapScale": 1.0,
    "_DstBlend": 0.0,
    "_GlossMapScale": 1.0,
    "_Glossiness": 0.5,
    "_GlossyReflections": 1.0,
    "_Metallic": 0.0,
    "_Mode": 0.0,
    "_OcclusionStrength": 1.0,
    "_Parallax": 0.02,
    "_SmoothnessTextureChannel": 0.0,
    "_SpecularHighlights": 1.0,
    "_SrcBlend": 1.0,
    "_UVSec": 0.0,
    "_ZWrite": 1.0,
}


def guid(name: str, namespace: str = "") -> str:
    """A Unity guid (32 lowercase hex digits) for an output file: a hash of ``namespace``
    and the file's name in the export folder, the same on every run (a re-export keeps
    Unity's references), different between exports of different ``namespace``."""
    return hashlib.md5(f"ctlab-unity\0{namespace}\0{name}".encode()).hexdigest()


def _number(x: float) -> str:
    text = fmt_float(x)
    return "0" if text in ("-0", "0") else text


_PLAIN = re.compile(r"[A-Za-z_][A-Za-z0-9 _.()+-]*")
# YAML 1.1's words for booleans and null, which a plain scalar would turn into
_WORDS = {"y", "n", "yes", "no", "true", "false", "on", "off", "null"}


def _scalar(text: str) -> str:
    """A YAML scalar for a name: plain where every YAML reader reads it back as the same
    text, else double-quoted, with the characters YAML may not hold raw escaped."""
    text = utf8_text(text)
    if _PLAIN.fullmatch(text) and not text.endswith(" ") and text.lower() not in _WORDS:
        return text
    out = []
    for c in text:
        if c in '"\\':
            out.append("\\" + c)
        elif c.isprintable() and c not in "\ufeff":
            out.append(c)
        elif ord(c) < 0x100:
            out.append(f"\\x{ord(c):02x}")
        elif ord(c) < 0x10000:
            out.append(f"\\u{ord(c):04x}")
        else:
            out.append(f"\\U{ord(c):08x}")
    return '"' + "".join(out) + '"'


def _texture_ref(file_guid: str | None) -> str:
    if not file_guid:
        return "{fileID: 0}"
    return f"{{fileID: {TEXTURE_FILE_ID}, guid: {file_guid}, type: 3}}"


def _color(rgba) -> str:
    r, g, b, a = (_number(c) for c in rgba)
    return f"{{r: {r}, g: {g}, b: {b}, a: {a}}}"


def mat_text(
    name: str,
    albedo=(1.0, 1.0, 1.0),
    metallic: float = 0.0,
    smoothness: float = 0.5,
    main_tex: str | None = None,
    metallic_gloss_map: str | None = None,
    bump_map: str | None = None,
    bump_scale: float = 1.0,
    tiling=(1.0, 1.0),
    offset=(0.0, 0.0),
) -> str:
    """A Standard (metallic) ``.mat``: ``albedo`` linear (written sRGB-encoded as
    ``_Color``), the textures by guid (None: none), ``_GlossMapScale`` 1 and
    ``_SmoothnessTextureChannel`` 0 (smoothness in the metallic-gloss map's A), the keywords
    Unity sets for the assigned maps, and ``_MainTex``'s ``tiling`` and ``offset`` (Standard
    reads every map with them)."""
    keywords = []
    if metallic_gloss_map:
        keywords.append("_METALLICGLOSSMAP")
    if bump_map:
        keywords.append("_NORMALMAP")
    floats = dict(_FLOATS)
    floats.update(
        _BumpScale=float(bump_scale),
        _Glossiness=float(smoothness),
        _Metallic=float(metallic),
        _GlossMapScale=1.0,
        _SmoothnessTextureChannel=0.0,
    )
    textures = {"_MainTex": main_tex, "_MetallicGlossMap": metallic_gloss_map, "_BumpMap": bump_map}
    color = tuple(linear_to_srgb(c) for c in tuple(albedo)[:3]) + (1.0,)
    lines = [
        "%YAML 1.1",
        "%TAG !u! tag:unity3d.com,2011:",
        f"--- !u!21 &{MATERIAL_FILE_ID}",
        "Material:",
        "  serializedVersion: 6",
        "  m_ObjectHideFlags: 0",
        "  m_CorrespondingSourceObject: {fileID: 0}",
        "  m_PrefabInstance: {fileID: 0}",
        "  m_PrefabAsset: {fileID: 0}",
        f"  m_Name: {_scalar(name)}",
        f"  m_Shader: {{fileID: {STANDARD}, guid: {BUILTIN_GUID}, type: 0}}",
        f"  m_ShaderKeywords: {' '.join(keywords)}".rstrip(),
        "  m_LightmapFlags: 4",
        "  m_EnableInstancingVariants: 0",
        "  m_DoubleSidedGI: 0",
        "  m_CustomRenderQueue: -1",
        "  stringTagMap: {}",
        "  disabledShaderPasses: []",
        "  m_SavedProperties:",
        "    serializedVersion: 3",
        "    m_TexEnvs:",
    ]
    for prop in _TEX_ENVS:
        sx, sy = tiling if prop == "_MainTex" else (1.0, 1.0)
        ox, oy = offset if prop == "_MainTex" else (0.0, 0.0)
        lines += [
            f"    - {prop}:",
            f"        m_Texture: {_texture_ref(textures.get(prop))}",
            f"        m_Scale: {{x: {_number(sx)}, y: {_number(sy)}}}",
            f"        m_Offset: {{x: {_number(ox)}, y: {_number(oy)}}}",
        ]
    lines.append("    m_Floats:")
    lines += [f"    - {prop}: {_number(value)}" for prop, value in floats.items()]
    lines += [
        "    m_Colors:",
        f"    - _Color: {_color(color)}",
        "    - _EmissionColor: {r: 0, g: 0, b: 0, a: 1}",
    ]
    return "\n".join(lines) + "\n"


_META_TAIL = ["  userData: ", "  assetBundleName: ", "  assetBundleVariant: "]


def material_meta(file_guid: str) -> str:
    """The ``.meta`` of a ``.mat`` (NativeFormatImporter)."""
    return (
        "\n".join(
            [
                "fileFormatVersion: 2",
                f"guid: {file_guid}",
                "NativeFormatImporter:",
                "  externalObjects: {}",
                f"  mainObjectFileID: {MATERIAL_FILE_ID}",
                *_META_TAIL,
            ]
        )
        + "\n"
    )


def folder_meta(file_guid: str) -> str:
    """The ``.meta`` of a folder (DefaultImporter, folderAsset)."""
    return (
        "\n".join(
            [
                "fileFormatVersion: 2",
                f"guid: {file_guid}",
                "folderAsset: yes",
                "DefaultImporter:",
                "  externalObjects: {}",
                *_META_TAIL,
            ]
        )
        + "\n"
    )


def texture_meta(file_guid: str, srgb: bool, normal_map: bool = False) -> str:
    """The ``.meta`` of a texture (TextureImporter): a normal map as Texture Type Normal map
    (textureType 1, linear), else Default with sRGB (Color Texture) as given; alpha kept as
    the file's (the packed map's smoothness)."""
    return (
        "\n".join(
            [
                "fileFormatVersion: 2",
                f"guid: {file_guid}",
                "TextureImporter:",
                "  internalIDToNameTable: []",
                "  externalObjects: {}",
                "  serializedVersion: 11",
                "  mipmaps:",
                "    mipMapMode: 0",
                "    enableMipMap: 1",
                f"    sRGBTexture: {0 if normal_map or not srgb else 1}",
                f"    linearTexture: {1 if normal_map or not srgb else 0}",
                "    fadeOut: 0",
                "    borderMipMap: 0",
                "    mipMapsPreserveCoverage: 0",
                "    alphaTestReferenceValue: 0.5",
                "    mipMapFadeDistanceStart: 1",
                "    mipMapFadeDistanceEnd: 3",
                "  bumpmap:",
                "    convertToNormalMap: 0",
                "    externalNormalMap: 0",
                "    heightScale: 0.25",
                "    normalMapFilter: 0",
                "  isReadable: 0",
                "  streamingMipmaps: 0",
                "  streamingMipmapsPriority: 0",
                "  grayScaleToAlpha: 0",
                "  generateCubemap: 6",
                "  cubemapConvolution: 0",
                "  seamlessCubemap: 0",
                "  textureFormat: 1",
                "  maxTextureSize: 2048",
                "  textureSettings:",
                "    serializedVersion: 2",
                "    filterMode: -1",
                "    aniso: -1",
                "    mipBias: -100",
                "    wrapU: -1",
                "    wrapV: -1",
                "    wrapW: -1",
                "  nPOTScale: 1",
                "  lightmap: 0",
                "  compressionQuality: 50",
                "  spriteMode: 0",
                "  alphaUsage: 1",
                "  alphaIsTransparency: 0",
                f"  textureType: {1 if normal_map else 0}",
                "  textureShape: 1",
                *_META_TAIL,
            ]
        )
        + "\n"
    )


def unity_not_carried(mat: Material) -> list:
    """What of the material Unity's Standard shader does not carry, in words (Standard is
    the model with Unity's Smith joint G, Disney diffuse, single scattering; it reads every
    map with ``_MainTex``'s tiling and offset, so only one UV mapping is carried)."""
    out = []
    if len({(t.uv_scale, t.uv_offset) for t in mat.textures.values()}) > 1:
        tiling, offset = _uv_of(mat)
        out.append(
            "maps with different UV mappings (Standard reads all of them with _MainTex's; "
            f"tiling {tiling} and offset {offset} written)"
        )
    if mat.g_model != "unity_smith_joint":
        out.append(f"G {mat.g_model} (Standard uses Unity's Smith joint approximation)")
    if mat.diffuse_model != "disney":
        out.append(f"{mat.diffuse_model} diffuse (Standard's is Disney)")
    if mat.energy != "none":
        out.append(f"energy {mat.energy} (Standard is single scattering)")
    if mat.units != "physical":
        out.append(f"units {mat.units} (the lab's; Unity's lights are Unity's)")
    return out


def unity_outputs(materials, texture_names=(), pixels=None, namespace: str = "") -> dict:
    """Unity's files for the export's materials, as relative path -> content:

    - ``<stem>.mat`` and ``<stem>.mat.meta`` per material (bytes, UTF-8 text); the stems are
      ``names.export_names``' (unique without case among the materials);
    - ``textures/<name>.meta`` (bytes) for each texture a ``.mat`` references: the albedo
      (sRGB as its image) and the normal map (Texture Type Normal map);
    - ``textures/<stem>_metallic_gloss.png`` as ``(PNG_RGBA, float32 array h x w x 4)``, for
      a material with a metallic or smoothness map, with its ``.meta`` (sRGB off): R = G =
      B = metallic, A = smoothness, made from ``pixels``;
    - ``textures.meta``, the folder's, when anything lies in it.

    ``texture_names``: the texture files the export copies (textures/NAME); a packed map's
    name avoids them. ``pixels``: file name -> that image's pixels (float, h x w x C, C >= 1,
    the file's values as read, not colour-decoded), needed for each metallic and smoothness
    map. The metallic and smoothness maps themselves are not referenced (the packed map
    replaces them): only the textures whose ``.meta`` is in the result need copying
    (``referenced_textures``). ``namespace`` goes into every guid (``guid``): pass the export's
    name (e.g. the .blend's stem) so that two exports into one Unity project do not share
    guids. Deterministic."""
    materials = list(materials)
    pixels = pixels or {}
    out = {}
    used = {name.casefold() for name in texture_names}
    used |= {t.file.casefold() for m in materials for t in m.textures.values()}
    for mat, names in zip(materials, export_names(materials)):
        stem = names.mtlx[: -len(".mtlx")]
        tex = mat.textures
        main = bump = packed = None
        if "albedo" in tex:
            main = tex["albedo"].file
            out[f"{main}.meta"] = texture_meta(
                guid(main, namespace), tex["albedo"].colorspace == "srgb_texture"
            ).encode()
        if "normal" in tex:
            bump = tex["normal"].file
            out[f"{bump}.meta"] = texture_meta(guid(bump, namespace), False, True).encode()
        if "metallic" in tex or "smoothness" in tex:
            packed = _packed_name(stem, used)
            maps = {
                key: texture_values(_channels(pixels, tex[key].file), tex[key])
                for key in ("metallic", "smoothness")
                if key in tex
            }
            image = metallic_gloss_pixels(
                maps.get("metallic"), maps.get("smoothness"), mat.metallic, mat.smoothness
            )
            out[packed] = (PNG_RGBA, image)
            out[f"{packed}.meta"] = texture_meta(guid(packed, namespace), False).encode()
        tiling, offset = _uv_of(mat)
        text = mat_text(
            mat.name,
            albedo=(tex["albedo"].tint or (1.0, 1.0, 1.0)) if main else mat.albedo,
            metallic=mat.metallic,
            smoothness=mat.smoothness,
            main_tex=guid(main, namespace) if main else None,
            metallic_gloss_map=guid(packed, namespace) if packed else None,
            bump_map=guid(bump, namespace) if bump else None,
            bump_scale=tex["normal"].strength if bump else 1.0,
            tiling=tiling,
            offset=offset,
        )
        out[f"{stem}.mat"] = text.encode("utf-8")
        out[f"{stem}.mat.meta"] = material_meta(guid(f"{stem}.mat", namespace)).encode()
    if any(k.startswith(TEXTURES) for k in out):
        folder = TEXTURES.rstrip("/")
        out[f"{folder}.meta"] = folder_meta(guid(folder, namespace)).encode()
    return out


def referenced_textures(materials) -> set:
    """The texture files (textures/NAME) the ``.mat`` files reference: albedo and normal."""
    return {
        m.textures[key].file for m in materials for key in ("albedo", "normal") if key in m.textures
    }


def _uv_of(mat: Material) -> tuple:
    """The UV mapping written as ``_MainTex``'s: the albedo map's, else the first map's."""
    order = [
        mat.textures[k] for k in ("albedo", "normal", "metallic", "smoothness") if k in mat.textures
    ]
    first = order[0] if order else None
    return (tuple(first.uv_scale), tuple(first.uv_offset)) if first else ((1.0, 1.0), (0.0, 0.0))


def _channels(pixels: dict, name: str):
    if name not in pixels:
        raise KeyError(f"unity_outputs needs the pixels of {name}")
    return pixels[name]


def _packed_name(stem: str, used: set) -> str:
    base = file_stem(stem, "material")
    name, i = f"{TEXTURES}{base}{PACKED_SUFFIX}", 1
    while name.casefold() in used:
        i += 1
        name = f"{TEXTURES}{base}_{i}{PACKED_SUFFIX}"
    used.add(name.casefold())
    return name
