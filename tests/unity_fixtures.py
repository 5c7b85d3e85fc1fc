"""Unity-format files of the tests' own making (no Unity, no bpy): ``.mat`` text in both
layouts of ``m_SavedProperties`` (Unity 5's first/second pairs, the flat list of 2017.3 and
later) and both keyword forms, ``.meta`` files with guids (new ``sRGBTexture`` and old
``linearTexture`` forms), tiny PNG textures written with zlib, and a project folder of them."""

from __future__ import annotations

import struct
import zlib
from pathlib import Path

import numpy as np

HEADER = "%YAML 1.1\n%TAG !u! tag:unity3d.com,2011:\n"
BUILTIN = "0000000000000000f000000000000000"


def png_bytes(rgba) -> bytes:
    """An 8-bit RGBA PNG of ``rgba`` (h x w x 4, values 0..1 or 0..255 integers)."""
    a = np.asarray(rgba)
    if a.dtype.kind == "f":
        a = np.clip(np.round(a * 255.0), 0, 255)
    a = a.astype(np.uint8)
    h, w, _ = a.shape
    raw = b"".join(b"\0" + a[y].tobytes() for y in range(h))

    def chunk(kind, data):
        return (
            struct.pack(">I", len(data))
            + kind
            + data
            + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)
        )

    return (
        b"\x89PNG\r\n\x1a\n"
        + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 6, 0, 0, 0))
        + chunk(b"IDAT", zlib.compress(raw))
        + chunk(b"IEND", b"")
    )


def texture_meta(guid: str, srgb: bool = True, normal: bool = False, old: bool = False) -> str:
    """A TextureImporter .meta: ``old``: Unity 5.4's ``linearTexture`` in place of
    ``sRGBTexture``."""
    colour = (
        f"    linearTexture: {0 if srgb else 1}\n"
        if old
        else f"    sRGBTexture: {1 if srgb else 0}\n"
    )
    return (
        f"fileFormatVersion: 2\nguid: {guid}\ntimeCreated: 1500000000\nlicenseType: Free\n"
        "TextureImporter:\n  fileIDToRecycleName: {}\n  serializedVersion: 4\n  mipmaps:\n"
        f"    mipMapMode: 0\n    enableMipMap: 1\n{colour}    fadeOut: 0\n"
        "  bumpmap:\n    convertToNormalMap: 0\n    heightScale: 0.25\n"
        f"  isReadable: 0\n  textureType: {1 if normal else 0}\n  userData: \n"
        "  assetBundleName: \n  assetBundleVariant: \n"
    )


def native_meta(guid: str) -> str:
    return (
        f"fileFormatVersion: 2\nguid: {guid}\nNativeFormatImporter:\n  externalObjects: {{}}\n"
        "  mainObjectFileID: 2100000\n  userData: \n  assetBundleName: \n"
        "  assetBundleVariant: \n"
    )


def _tex(guid):
    return "{fileID: 0}" if not guid else f"{{fileID: 2800000, guid: {guid}, type: 3}}"


def mat_flat(
    name,
    shader="{fileID: 46, guid: " + BUILTIN + ", type: 0}",
    textures=None,
    floats=None,
    colors=None,
    keywords=(),
    version=8,
    extra_document=True,
) -> str:
    """A .mat of the flat layout: ``version`` 8 (m_ValidKeywords lists, m_Ints) or 6 (one
    keyword string). ``textures``: prop -> (guid, (sx, sy), (ox, oy))."""
    textures = textures or {}
    lines = [
        "--- !u!21 &2100000",
        "Material:",
        f"  serializedVersion: {version}",
        "  m_ObjectHideFlags: 0",
        "  m_CorrespondingSourceObject: {fileID: 0}",
        "  m_PrefabInstance: {fileID: 0}",
        "  m_PrefabAsset: {fileID: 0}",
        f"  m_Name: {name}",
        f"  m_Shader: {shader}",
    ]
    if version >= 8:
        if keywords:
            lines.append("  m_ValidKeywords:")
            lines += [f"  - {k}" for k in keywords]
        else:
            lines.append("  m_ValidKeywords: []")
        lines.append("  m_InvalidKeywords: []")
    else:
        lines.append(f"  m_ShaderKeywords: {' '.join(keywords)}")
    lines += [
        "  m_LightmapFlags: 4",
        "  m_CustomRenderQueue: -1",
        "  stringTagMap: {}",
        "  disabledShaderPasses: []",
        "  m_SavedProperties:",
        "    serializedVersion: 3",
        "    m_TexEnvs:",
    ]
    for prop in sorted(set(textures) | {"_MainTex", "_BumpMap", "_MetallicGlossMap"}):
        guid, scale, offset = textures.get(prop, (None, (1, 1), (0, 0)))
        lines += [
            f"    - {prop}:",
            f"        m_Texture: {_tex(guid)}",
            f"        m_Scale: {{x: {scale[0]}, y: {scale[1]}}}",
            f"        m_Offset: {{x: {offset[0]}, y: {offset[1]}}}",
        ]
    if version >= 8:
        lines.append("    m_Ints: []")
    lines.append("    m_Floats:")
    lines += [f"    - {k}: {v}" for k, v in (floats or {}).items()]
    lines.append("    m_Colors:")
    lines += [
        f"    - {k}: {{r: {c[0]}, g: {c[1]}, b: {c[2]}, a: {c[3]}}}"
        for k, c in (colors or {}).items()
    ]
    lines.append("  m_BuildTextureStacks: []")
    text = HEADER + "\n".join(lines) + "\n"
    if extra_document:
        # a second document, as URP/HDRP's version stamps add (the !u! handle undeclared)
        text += (
            "--- !u!114 &5726066890436045427\nMonoBehaviour:\n  m_ObjectHideFlags: 11\n"
            "  m_Script: {fileID: 11500000, guid: d0353a89b1f911e48b9e16bdc9f2e058, type: 3}\n"
            "  m_Name: \n  version: 7\n"
        )
    return text


def mat_pairs(name, shader_file_id=46, textures=None, floats=None, colors=None, keywords=()):
    """A .mat of Unity 5's layout: ``- first: {name: X} second: ...`` pairs, keywords as one
    string (Material serializedVersion 6, m_SavedProperties serializedVersion 2)."""
    textures = textures or {}
    lines = [
        "--- !u!21 &2100000",
        "Material:",
        "  serializedVersion: 6",
        "  m_ObjectHideFlags: 0",
        "  m_PrefabParentObject: {fileID: 0}",
        "  m_PrefabInternal: {fileID: 0}",
        f"  m_Name: {name}",
        f"  m_Shader: {{fileID: {shader_file_id}, guid: {BUILTIN}, type: 0}}",
        f"  m_ShaderKeywords: {' '.join(keywords)}",
        "  m_LightmapFlags: 5",
        "  m_CustomRenderQueue: -1",
        "  stringTagMap: {}",
        "  m_SavedProperties:",
        "    serializedVersion: 2",
        "    m_TexEnvs:",
    ]
    for prop in sorted(set(textures) | {"_MainTex", "_BumpMap"}):
        guid, scale, offset = textures.get(prop, (None, (1, 1), (0, 0)))
        lines += [
            "    - first:",
            f"        name: {prop}",
            "      second:",
            f"        m_Texture: {_tex(guid)}",
            f"        m_Scale: {{x: {scale[0]}, y: {scale[1]}}}",
            f"        m_Offset: {{x: {offset[0]}, y: {offset[1]}}}",
        ]
    lines.append("    m_Floats:")
    for k, v in (floats or {}).items():
        lines += ["    - first:", f"        name: {k}", f"      second: {v}"]
    lines.append("    m_Colors:")
    for k, c in (colors or {}).items():
        lines += [
            "    - first:",
            f"        name: {k}",
            f"      second: {{r: {c[0]}, g: {c[1]}, b: {c[2]}, a: {c[3]}}}",
        ]
    return HEADER + "\n".join(lines) + "\n"


UNITY4 = HEADER + (
    "--- !u!21 &2100000\nMaterial:\n  serializedVersion: 3\n  m_ObjectHideFlags: 0\n"
    "  m_Name: Ancient\n  m_Shader: {fileID: 46, guid: " + BUILTIN + ", type: 0}\n"
    "  m_SavedProperties:\n    serializedVersion: 2\n    m_TexEnvs:\n      data:\n"
    "        first:\n          name: _MainTex\n        second:\n"
    "          m_Texture: {fileID: 0}\n          m_Scale: {x: 1, y: 1}\n"
    "          m_Offset: {x: 0, y: 0}\n    m_Floats:\n      data:\n        first:\n"
    "          name: _Metallic\n        second: 0\n"
)

# guids of the fixture project (one all digits with a leading zero: YAML 1.1 reads that as
# an octal number unless the loader keeps scalars as text)
G_ALBEDO = "0123456701234567012345670123456a"
G_METAL = "01234567012345670123456701234567"
G_NORMAL = "5f0e8a3d2c1b4a9f8e7d6c5b4a392817"
G_ALBEDO_A = "a1b2c3d4e5f60718293a4b5c6d7e8f90"
G_TOON = "9d8c7b6a5f4e3d2c1b0a998877665544"
G_GONE = "deadbeefdeadbeefdeadbeefdeadbeef"

# The values the fixture materials hold
BRICK_COLOR = (0.8, 0.6, 0.4, 1.0)  # sRGB, as the inspector shows it
OLD_COLOR = (0.5, 0.25, 0.75, 1.0)


def albedo_pixels():
    px = np.zeros((4, 4, 4))
    px[..., 0] = np.linspace(0.1, 0.9, 4)[None, :]
    px[..., 1] = 0.5
    px[..., 2] = np.linspace(0.9, 0.2, 4)[:, None]
    px[..., 3] = 1.0
    return px


def metal_pixels():
    px = np.zeros((4, 4, 4))
    px[..., 0] = np.linspace(0.0, 1.0, 4)[None, :]  # metallic
    px[..., 3] = np.linspace(0.2, 0.9, 4)[:, None]  # smoothness
    return px


def albedo_alpha_pixels():
    px = albedo_pixels()
    px[..., 3] = np.linspace(0.3, 1.0, 4)[:, None]
    return px


def normal_pixels():
    px = np.zeros((4, 4, 4))
    px[..., 0], px[..., 1], px[..., 2], px[..., 3] = 0.6, 0.45, 0.9, 1.0
    return px


def write_project(root: Path) -> Path:
    """A Unity project folder (root/Assets/...) of every case the import reads."""
    assets = root / "Assets"
    (assets / "Textures").mkdir(parents=True)
    (assets / "Materials").mkdir()
    (assets / "Shaders").mkdir()
    (root / "ProjectSettings").mkdir()
    (root / "ProjectSettings" / "ProjectVersion.txt").write_text("m_EditorVersion: 2022.3.1f1\n")
    textures = {
        "albedo.png": (G_ALBEDO, albedo_pixels(), dict(srgb=True)),
        "metal.png": (G_METAL, metal_pixels(), dict(srgb=True)),  # Unity's default: sRGB
        "normal.png": (G_NORMAL, normal_pixels(), dict(srgb=False, normal=True, old=True)),
        "albedo_a.png": (G_ALBEDO_A, albedo_alpha_pixels(), dict(srgb=True)),
    }
    for name, (guid, px, meta) in textures.items():
        (assets / "Textures" / name).write_bytes(png_bytes(px))
        (assets / "Textures" / f"{name}.meta").write_text(texture_meta(guid, **meta))
    (assets / "Shaders" / "Toon.shader").write_text('Shader "Custom/Toon" { }\n')
    (assets / "Shaders" / "Toon.shader.meta").write_text(
        f"fileFormatVersion: 2\nguid: {G_TOON}\nShaderImporter:\n  userData: \n"
    )
    mats = {
        "Brick.mat": mat_flat(
            "Brick",
            textures={
                "_MainTex": (G_ALBEDO, (2, 3), (0.25, 0.5)),
                "_MetallicGlossMap": (G_METAL, (1, 1), (0, 0)),
                "_BumpMap": (G_NORMAL, (1, 1), (0, 0)),
                "_OcclusionMap": (G_ALBEDO, (1, 1), (0, 0)),
            },
            floats={
                "_Metallic": 0.9,
                "_Glossiness": 0.1,
                "_GlossMapScale": 0.8,
                "_BumpScale": 0.5,
                "_SmoothnessTextureChannel": 0,
            },
            colors={"_Color": BRICK_COLOR, "_EmissionColor": (0, 0, 0, 1)},
            keywords=("_NORMALMAP",),  # stale: the metallic map is assigned
        ),
        "Old.mat": mat_pairs(
            "Old",
            floats={"_Metallic": 0.3, "_Glossiness": 0.65, "_BumpScale": 1},
            colors={"_Color": OLD_COLOR},
        ),
        "AlbedoAlpha.mat": mat_flat(
            "AlbedoAlpha",
            textures={
                "_MainTex": (G_ALBEDO_A, (1, 1), (0, 0)),
                "_MetallicGlossMap": (G_METAL, (1, 1), (0, 0)),
            },
            floats={"_SmoothnessTextureChannel": 1, "_GlossMapScale": 0.5, "_Glossiness": 0.9},
            colors={"_Color": (1, 1, 1, 1)},
            version=6,
            extra_document=False,
        ),
        "Missing.mat": mat_flat(
            "Missing",
            textures={"_MainTex": (G_GONE, (1, 1), (0, 0))},
            floats={"_Metallic": 0.25, "_Glossiness": 0.75},
            colors={"_Color": (0.2, 0.4, 0.6, 1)},
        ),
        "Spec.mat": mat_pairs("Spec", shader_file_id=45),
        "Autodesk.mat": mat_flat("Autodesk", shader="{fileID: 47, guid: " + BUILTIN + ", type: 0}"),
        "Toon.mat": mat_flat("Toon", shader=f"{{fileID: 4800000, guid: {G_TOON}, type: 3}}"),
    }
    for i, (name, text) in enumerate(sorted(mats.items())):
        (assets / "Materials" / name).write_text(text)
        (assets / "Materials" / f"{name}.meta").write_text(native_meta(f"{i + 1:032x}"))
    return root


def snapshot(root: Path) -> dict:
    """Every file and folder under ``root``: its bytes and modification time."""
    out = {}
    for p in sorted(Path(root).rglob("*")):
        st = p.stat()
        out[str(p.relative_to(root))] = (p.read_bytes() if p.is_file() else None, st.st_mtime_ns)
    return out
