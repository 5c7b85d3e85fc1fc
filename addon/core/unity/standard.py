"""What a Unity project folder holds (every asset's guid from its ``.meta``, every ``.mat``) and
what a built-in Standard (metallic) material means for the model (``surface``: docs/usage.md,
"To and from Unity"); the files themselves are read by core/unity/read.py.

Standard's meaning, from its shader source (UnityStandardInput.cginc, ``MetallicGloss``):
with ``_MetallicGlossMap`` assigned, metallic = its R and smoothness = its A (or, with
``_SmoothnessTextureChannel`` 1, ``_MainTex``'s A) times ``_GlossMapScale``, and ``_Metallic``
and ``_Glossiness`` are ignored; without it metallic = ``_Metallic`` and smoothness =
``_Glossiness`` (or ``_MainTex``'s A times ``_GlossMapScale``). The keywords in real files are
often stale: the assigned textures decide."""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

from ..errors import UserError
from .read import (
    BUILTIN_GUID,
    BUILTIN_SHADERS,
    UnityMaterial,
    read_meta,
    read_text,
)

# Standard's textures the model does not carry, and what they are
NOT_CARRIED_MAPS = {
    "_OcclusionMap": "occlusion map",
    "_ParallaxMap": "parallax (height) map",
    "_EmissionMap": "emission map",
    "_DetailMask": "detail mask",
    "_DetailAlbedoMap": "detail albedo map",
    "_DetailNormalMap": "detail normal map",
}
MODES = {1: "Cutout", 2: "Fade", 3: "Transparent"}
# Folders of a Unity project that hold no assets of its own (or only derived ones)
PROJECT_ROOTS = ("Assets", "Packages")

# ---------------------------------------------------------------------------------------
# A project folder


@dataclass
class Project:
    """The assets found under the roots: guid -> (asset path, Meta); the ``.mat`` files."""

    roots: list
    assets: dict = field(default_factory=dict)
    materials: list = field(default_factory=list)
    problems: list = field(default_factory=list)  # unreadable .meta files, in words


def project_roots(path: Path) -> list:
    """Where a folder's assets lie: a Unity project's Assets (and Packages), or the folder."""
    path = Path(path)
    if (path / "Assets").is_dir():
        return [path / name for name in PROJECT_ROOTS if (path / name).is_dir()]
    return [path]


def assets_root_of(mat_file: Path) -> Path:
    """The folder whose guids a lone ``.mat`` resolves against: its nearest ``Assets``
    ancestor, else its own folder."""
    for parent in Path(mat_file).parents:
        if parent.name == "Assets":
            return parent
    return Path(mat_file).parent


def _walk(root: Path):
    """Every file under ``root``, in sorted order; no link followed, and no folder Unity
    ignores (hidden, or ending in '~')."""
    for folder, dirs, names in os.walk(root, followlinks=False):
        dirs[:] = sorted(d for d in dirs if not d.startswith(".") and not d.endswith("~"))
        for name in sorted(names):
            if not name.startswith("."):
                yield Path(folder) / name


def scan(roots) -> Project:
    """Every asset's guid (from its ``.meta``) and every ``.mat`` under ``roots``; nothing is
    written. A ``.meta`` that cannot be read is a problem in words, not an error."""
    project = Project(roots=[Path(r) for r in roots])
    for root in project.roots:
        for path in _walk(root):
            if path.suffix == ".meta":
                asset = path.with_suffix("")
                try:
                    meta = read_meta(read_text(path, ".meta file"), str(path))
                except UserError as exc:
                    project.problems.append(str(exc))
                    continue
                project.assets.setdefault(meta.guid, (asset, meta))
            elif path.suffix == ".mat" and path.is_file():
                project.materials.append(path)
    return project


# ---------------------------------------------------------------------------------------
# What a Standard material means for the model


def srgb_to_linear(c: float) -> float:
    """Unity's GammaToLinearSpace (the sRGB curve), per channel."""
    c = float(c)
    if c <= 0.04045:
        return c / 12.92
    return ((c + 0.055) / 1.055) ** 2.4


def linear_to_srgb(c: float) -> float:
    """Unity's LinearToGammaSpace (the sRGB curve), per channel."""
    c = max(float(c), 0.0)
    if c <= 0.0031308:
        return c * 12.92
    return 1.055 * c ** (1.0 / 2.4) - 0.055


@dataclass(frozen=True)
class Map:
    """A texture the model reads: its file and whether it is decoded as sRGB."""

    path: str
    srgb: bool
    normal_map: bool = False


@dataclass(frozen=True)
class Surface:
    """A Standard material as the model's inputs.

    - albedo = ``albedo`` (``_Color`` decoded to linear) times ``albedo_map`` when there is one
    - metallic = ``metallic_map``'s R when there is one, else ``metallic``
    - smoothness: ``smoothness_from`` "constant" (``smoothness``), "metallic_map" (its A) or
      "albedo_map" (its A), times ``gloss_map_scale`` for the maps
    - normal: ``normal_map`` through a tangent-space Normal Map node of strength ``bump_scale``
    - every map read at UV * ``tiling`` + ``offset`` (``_MainTex``'s, as Standard does)
    """

    name: str
    source: str
    albedo: tuple = (1.0, 1.0, 1.0)
    metallic: float = 0.0
    smoothness: float = 0.5
    gloss_map_scale: float = 1.0
    smoothness_from: str = "constant"
    albedo_map: Map | None = None
    metallic_map: Map | None = None
    normal_map: Map | None = None
    bump_scale: float = 1.0
    tiling: tuple = (1.0, 1.0)
    offset: tuple = (0.0, 0.0)
    warnings: tuple = ()  # missing textures, in words
    not_carried: tuple = ()  # what of the material the model leaves out, in words


def shader_label(mat: UnityMaterial, project: Project | None = None) -> str:
    """The shader a material uses, in words: a built-in's name, or a shader asset's file."""
    if mat.shader_guid == BUILTIN_GUID:
        name = BUILTIN_SHADERS.get(mat.shader_file_id)
        return name or f"built-in shader fileID {mat.shader_file_id}"
    if project is not None and mat.shader_guid in project.assets:
        return f"shader {project.assets[mat.shader_guid][0].name}"
    return f"shader guid {mat.shader_guid or 'none'} (fileID {mat.shader_file_id})"


def _map(mat: UnityMaterial, prop: str, assets: dict, warnings: list):
    ref = mat.texture(prop)
    if not ref.guid:
        return None
    found = assets.get(ref.guid)
    if found is None:
        warnings.append(
            f"{mat.name}: {prop}'s texture (guid {ref.guid}) resolves to no .meta file under "
            "the folder; the material is kept without it"
        )
        return None
    path, meta = found
    if not Path(path).is_file():
        warnings.append(f"{mat.name}: {prop}'s texture {path} is missing; kept without it")
        return None
    return Map(str(path), meta.srgb, meta.normal_map)


def surface(mat: UnityMaterial, assets: dict) -> Surface:
    """What a Standard material means for the model (this module's docstring): ``assets``
    is guid -> (path, Meta) (``Project.assets``)."""
    warnings, notes = [], []
    color = mat.color("_Color")
    albedo = tuple(srgb_to_linear(c) for c in color[:3])
    albedo_map = _map(mat, "_MainTex", assets, warnings)
    metallic_map = _map(mat, "_MetallicGlossMap", assets, warnings)
    normal_map = _map(mat, "_BumpMap", assets, warnings)
    if normal_map is not None and not normal_map.normal_map:
        notes.append(
            "_BumpMap's texture is not imported as a normal map in Unity (Texture Type); "
            "read as a linear tangent-space normal map"
        )
    if normal_map is not None:
        normal_map = Map(normal_map.path, False, True)
    channel = int(round(mat.float("_SmoothnessTextureChannel")))
    if channel == 1:
        smoothness_from = "albedo_map" if albedo_map is not None else "constant"
    else:
        smoothness_from = "metallic_map" if metallic_map is not None else "constant"
    gloss_scale = mat.float("_GlossMapScale")
    if smoothness_from == "constant":
        # Standard: channel 1 without _MainTex reads Unity's white texture (alpha 1)
        smoothness = gloss_scale if channel == 1 else mat.float("_Glossiness")
    else:
        smoothness = mat.float("_Glossiness")  # unused: the map holds it
    main = mat.texture("_MainTex")
    for prop, what in NOT_CARRIED_MAPS.items():
        if mat.texture(prop).guid:
            notes.append(f"{what} ({prop}) not carried")
    emission = mat.color("_EmissionColor")[:3] if "_EmissionColor" in mat.colors else (0, 0, 0)
    if "_EMISSION" in mat.keywords and any(c > 0 for c in emission):
        notes.append("emission (_EmissionColor) not carried")
    mode = int(round(mat.float("_Mode")))
    if mode in MODES:
        notes.append(f"rendering mode {MODES[mode]} (_Mode {mode}) not carried: imported opaque")
    if abs(color[3] - 1.0) > 1e-6 and mode in MODES:
        notes.append(f"_Color's alpha {color[3]:g} not carried")
    if mat.float("_SpecularHighlights") == 0 and "_SpecularHighlights" in mat.floats:
        notes.append("Specular Highlights off not carried")
    if mat.float("_GlossyReflections") == 0 and "_GlossyReflections" in mat.floats:
        notes.append("Reflections off not carried")
    return Surface(
        name=mat.name,
        source=mat.source,
        albedo=albedo,
        metallic=mat.float("_Metallic"),
        smoothness=smoothness,
        gloss_map_scale=gloss_scale,
        smoothness_from=smoothness_from,
        albedo_map=albedo_map,
        metallic_map=metallic_map,
        normal_map=normal_map,
        bump_scale=mat.float("_BumpScale"),
        tiling=main.scale,
        offset=main.offset,
        warnings=tuple(warnings),
        not_carried=tuple(notes),
    )


def effective_smoothness(s: Surface, albedo_alpha: float = 1.0, gloss_alpha: float = 1.0):
    """The smoothness Standard computes at a point whose maps' alphas are given."""
    if s.smoothness_from == "metallic_map":
        return gloss_alpha * s.gloss_map_scale
    if s.smoothness_from == "albedo_map":
        return albedo_alpha * s.gloss_map_scale
    return s.smoothness
