"""Reading Unity's material files: a ``.mat`` (the built-in Standard shader's properties), the
``.meta`` files that give each asset its guid and a texture its import settings, and a
project folder's guids; and what a Standard (metallic) material means for the model
(``surface``): docs/usage.md, "To and from Unity".

Parsed with PyYAML (a SafeLoader subclass): Unity's tags (``--- !u!21 &2100000``, the
``%TAG !u! tag:unity3d.com,2011:`` directive, which Unity writes once for every document of
the file) are known to each document; every plain scalar stays a string (a guid such as
``00000000000000001000000000000000`` must not become a number), and numbers are read where
a value is used. Both layouts of ``m_SavedProperties``: Unity 5's ``- first: {name: _Color}
second: ...`` pairs and the flat ``- _Color: {r: ...}`` form of 2017.3 and later; the keywords
as a string (Material serializedVersion 6) or ``m_ValidKeywords`` (8). Unity 4's layout (a
mapping of repeated ``data:`` keys) and binary files are refused.

Standard's meaning, from its shader source (UnityStandardInput.cginc, ``MetallicGloss``):
with ``_MetallicGlossMap`` assigned, metallic = its R and smoothness = its A (or, with
``_SmoothnessTextureChannel`` 1, ``_MainTex``'s A) times ``_GlossMapScale``, and ``_Metallic``
and ``_Glossiness`` are ignored; without it metallic = ``_Metallic`` and smoothness =
``_Glossiness`` (or ``_MainTex``'s A times ``_GlossMapScale``). The keywords in real files are
often stale: the assigned textures decide."""

from __future__ import annotations

import math
import os
import re
from dataclasses import dataclass, field
from pathlib import Path

from ..errors import UserError

# The built-in shaders, by fileID, with guid 0000000000000000f000000000000000
BUILTIN_GUID = "0000000000000000f000000000000000"
STANDARD = 46
BUILTIN_SHADERS = {
    45: "Standard (Specular setup)",
    46: "Standard",
    47: "Autodesk Interactive",
}
MATERIAL_CLASS = "21"
TEXTURE_FILE_ID = 2800000
UNITY_TAG = "tag:unity3d.com,2011:"
NORMAL_MAP_TYPE = 1  # TextureImporter textureType of a normal map

# Standard's defaults (Standard.shader's Properties) for what a file may leave out
DEFAULTS = {
    "_Color": (1.0, 1.0, 1.0, 1.0),
    "_Metallic": 0.0,
    "_Glossiness": 0.5,
    "_GlossMapScale": 1.0,
    "_SmoothnessTextureChannel": 0.0,
    "_BumpScale": 1.0,
    "_Mode": 0.0,
}
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
# YAML with Unity's tags


def _yaml():
    try:
        import yaml
    except ImportError:
        raise UserError(
            "reading Unity files needs PyYAML (pip install pyyaml), which this Python lacks"
        ) from None
    return yaml


_LOADER = None


def _loader():
    """A SafeLoader subclass: Unity's ``!u!`` handle known to every document, Unity's tags
    constructed as plain mappings (a ``UnityDocument``), every plain scalar a string."""
    global _LOADER
    if _LOADER is not None:
        return _LOADER
    yaml = _yaml()

    class UnityLoader(yaml.SafeLoader):
        # PyYAML resets a document's tag handles to these: Unity's files declare ``!u!`` only
        # before the first document and use it in all of them
        DEFAULT_TAGS = {"!": "!", "!!": "tag:yaml.org,2002:", "!u!": UNITY_TAG}

    # no implicit types: numbers are read where they are used, guids stay text
    UnityLoader.yaml_implicit_resolvers = {}

    def unity_object(loader, suffix, node):
        if isinstance(node, yaml.MappingNode):
            doc = UnityDocument(loader.construct_mapping(node, deep=True))
        else:
            doc = UnityDocument()
        doc.class_id = suffix
        return doc

    UnityLoader.add_multi_constructor(UNITY_TAG, unity_object)
    _LOADER = UnityLoader
    return _LOADER


class UnityDocument(dict):
    """One document of a Unity file: its mapping, and its class id (``!u!21``: "21")."""

    class_id = ""


# Prefab documents may say "stripped" after the anchor, which YAML does not allow
_STRIPPED = re.compile(r"^(--- !u!-?\d+ &-?\d+) stripped[ \t]*$", re.M)


def load_documents(text: str, where: str) -> list:
    """Every YAML document of a Unity file, or a UserError (one line) naming ``where``."""
    yaml = _yaml()
    if "\0" in text:
        raise UserError(
            f"{where} is not a text file (Unity's binary serialization?); set Asset "
            "Serialization to Force Text in Unity and save it again"
        )
    try:
        return [d for d in yaml.load_all(_STRIPPED.sub(r"\1", text), Loader=_loader())]
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        at = f" at line {mark.line + 1}" if mark is not None else ""
        problem = getattr(exc, "problem", None) or type(exc).__name__
        raise UserError(f"{where} is not YAML ({problem}{at})") from None
    except RecursionError:
        raise UserError(f"{where} is not YAML (nested too deeply)") from None


def read_text(path: Path, what: str) -> str:
    try:
        data = Path(path).read_bytes()
    except OSError as exc:
        raise UserError(f"{what} {path} cannot be read ({exc.strerror or exc})") from None
    if b"\0" in data[:4096]:
        raise UserError(
            f"{what} {path} is not YAML (a binary file: Unity's binary "
            "serialization? set Asset Serialization to Force Text in Unity)"
        )
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError:
        raise UserError(f"{what} {path} is not YAML (not UTF-8 text)") from None


# ---------------------------------------------------------------------------------------
# Numbers and references


def number(value, default: float = 0.0) -> float:
    """A Unity number as text (or a number), or ``default`` where it is none."""
    if value is None or isinstance(value, (dict, list)):
        return default
    try:
        x = float(str(value).strip())
    except ValueError:
        return default
    return x if math.isfinite(x) else default


def _file_id(value) -> int:
    try:
        return int(str(value).strip())
    except (TypeError, ValueError):
        return 0


def _guid(value) -> str:
    text = "" if value is None else str(value).strip().lower()
    return "" if not text or set(text) == {"0"} else text


@dataclass(frozen=True)
class TextureRef:
    """A texture slot of a material: the asset's guid ("" none), its tiling and offset."""

    guid: str = ""
    file_id: int = 0
    scale: tuple = (1.0, 1.0)
    offset: tuple = (0.0, 0.0)


@dataclass(frozen=True)
class UnityMaterial:
    """A ``.mat``'s material: its name, shader reference, properties and keywords."""

    name: str
    shader_file_id: int
    shader_guid: str
    textures: dict = field(default_factory=dict)  # property -> TextureRef
    floats: dict = field(default_factory=dict)  # property -> float
    colors: dict = field(default_factory=dict)  # property -> (r, g, b, a)
    keywords: tuple = ()
    layout: str = "flat"  # "pairs" (Unity 5) or "flat"
    source: str = ""  # the file, for messages

    @property
    def is_standard(self) -> bool:
        """Exactly the built-in Standard (metallic) shader: fileID 46 and the built-in guid.
        45 (Specular setup) and 47 (Autodesk Interactive) share its property names."""
        return self.shader_file_id == STANDARD and self.shader_guid == BUILTIN_GUID

    def float(self, name: str) -> float:
        return self.floats.get(name, DEFAULTS.get(name, 0.0))

    def color(self, name: str) -> tuple:
        return self.colors.get(name, DEFAULTS.get(name, (0.0, 0.0, 0.0, 0.0)))

    def texture(self, name: str) -> TextureRef:
        return self.textures.get(name, TextureRef())


def _pairs(entries, what: str, where: str):
    """(name, value) of a property list in either layout; the layout's name."""
    if entries is None or entries == "":
        return [], None
    if isinstance(entries, dict):
        if not entries:
            return [], None
        raise UserError(
            f"{where}: {what} is a mapping (Unity 4's layout), which this reader does not "
            "read; open the project in Unity 5 or later and save the material again"
        )
    if not isinstance(entries, list):
        raise UserError(f"{where}: {what} is not a list; not a material layout this reader knows")
    out, layout = [], None
    for entry in entries:
        if not isinstance(entry, dict):
            raise UserError(f"{where}: an entry of {what} is not a mapping")
        if "first" in entry and "second" in entry:
            first = entry["first"]
            name = first.get("name") if isinstance(first, dict) else first
            out.append((str(name), entry["second"]))
            layout = "pairs"
        elif len(entry) == 1:
            ((name, value),) = entry.items()
            out.append((str(name), value))
            layout = layout or "flat"
        else:
            raise UserError(f"{where}: an entry of {what} is neither a pair nor a property")
    return out, layout


def _vec2(value, keys, default) -> tuple:
    if not isinstance(value, dict):
        return default
    return tuple(number(value.get(k), d) for k, d in zip(keys, default))


def parse_material(documents: list, where: str) -> UnityMaterial:
    """The material of a ``.mat``'s documents (the one of class 21, ``Material:``), or a
    UserError: not a material, or a layout this reader does not know."""
    body = None
    for doc in documents:
        if isinstance(doc, dict) and isinstance(doc.get("Material"), dict):
            if isinstance(doc, UnityDocument) and doc.class_id not in ("", MATERIAL_CLASS):
                continue
            body = doc["Material"]
            break
    if body is None:
        raise UserError(f"{where} holds no Unity material (no 'Material' document)")
    shader = body.get("m_Shader")
    if not isinstance(shader, dict):
        raise UserError(f"{where}: its material has no m_Shader reference")
    props = body.get("m_SavedProperties")
    if props is None:
        props = {}
    if not isinstance(props, dict):
        raise UserError(
            f"{where}: m_SavedProperties is not a mapping; not a layout this reader knows"
        )
    textures, floats, colors, layouts = {}, {}, {}, set()
    entries, layout = _pairs(props.get("m_TexEnvs"), "m_TexEnvs", where)
    layouts.add(layout)
    for name, value in entries:
        if not isinstance(value, dict):
            continue
        tex = value.get("m_Texture")
        tex = tex if isinstance(tex, dict) else {}
        textures[name] = TextureRef(
            guid=_guid(tex.get("guid")),
            file_id=_file_id(tex.get("fileID")),
            scale=_vec2(value.get("m_Scale"), ("x", "y"), (1.0, 1.0)),
            offset=_vec2(value.get("m_Offset"), ("x", "y"), (0.0, 0.0)),
        )
    for key in ("m_Floats", "m_Ints"):
        entries, layout = _pairs(props.get(key), key, where)
        layouts.add(layout)
        for name, value in entries:
            floats[name] = number(value, DEFAULTS.get(name, 0.0))
    entries, layout = _pairs(props.get("m_Colors"), "m_Colors", where)
    layouts.add(layout)
    for name, value in entries:
        colors[name] = _vec2(value, ("r", "g", "b", "a"), (0.0, 0.0, 0.0, 1.0))
    keywords = body.get("m_ValidKeywords")
    if isinstance(keywords, list):
        keywords = tuple(str(k) for k in keywords)
    else:
        text = body.get("m_ShaderKeywords")
        keywords = tuple(str(text).split()) if isinstance(text, str) else ()
    layouts.discard(None)
    name = body.get("m_Name")
    return UnityMaterial(
        name=str(name) if name not in (None, "") else Path(where).stem,
        shader_file_id=_file_id(shader.get("fileID")),
        shader_guid=_guid(shader.get("guid")),
        textures=textures,
        floats=floats,
        colors=colors,
        keywords=keywords,
        layout="pairs" if "pairs" in layouts else "flat",
        source=where,
    )


def read_material(text: str, where: str) -> UnityMaterial:
    """A ``.mat``'s text as a UnityMaterial (``where``: its name in messages)."""
    return parse_material(load_documents(text, where), where)


# ---------------------------------------------------------------------------------------
# .meta files


@dataclass(frozen=True)
class Meta:
    """A ``.meta`` file: the asset's guid, and for a texture whether Unity decodes it as sRGB
    and whether it is imported as a normal map."""

    guid: str
    importer: str = ""
    srgb: bool = True
    normal_map: bool = False


def read_meta(text: str, where: str) -> Meta:
    docs = load_documents(text, where)
    doc = next((d for d in docs if isinstance(d, dict)), None)
    if doc is None or not _guid(doc.get("guid")):
        raise UserError(f"{where} is not a Unity .meta file (no guid)")
    importer = next((k for k in doc if str(k).endswith("Importer")), "")
    settings = doc.get(importer) if importer else None
    settings = settings if isinstance(settings, dict) else {}
    mip = settings.get("mipmaps") if isinstance(settings.get("mipmaps"), dict) else {}

    def setting(key):
        for where_ in (settings, mip):
            if key in where_:
                return where_[key]
        return None

    texture_type = _file_id(setting("textureType"))
    srgb_value, linear = setting("sRGBTexture"), setting("linearTexture")
    if srgb_value is not None:
        srgb = number(srgb_value, 1.0) != 0
    elif linear is not None:  # old files (Unity 5.4 and before)
        srgb = number(linear, 0.0) == 0
    else:
        srgb = True
    normal = texture_type == NORMAL_MAP_TYPE
    return Meta(_guid(doc.get("guid")), importer, srgb and not normal, normal)


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
