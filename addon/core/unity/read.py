"""Reading Unity's material files: a ``.mat`` (the built-in Standard shader's properties), the
``.meta`` files that give each asset its guid and a texture its import settings. A project
folder's guids, and what a Standard (metallic) material means for the model, are
core/unity/standard.py.

Parsed with PyYAML (a SafeLoader subclass): Unity's tags (``--- !u!21 &2100000``, the
``%TAG !u! tag:unity3d.com,2011:`` directive, which Unity writes once for every document of
the file) are known to each document; every plain scalar stays a string (a guid such as
``00000000000000001000000000000000`` must not become a number), and numbers are read where
a value is used. Both layouts of ``m_SavedProperties``: Unity 5's ``- first: {name: _Color}
second: ...`` pairs and the flat ``- _Color: {r: ...}`` form of 2017.3 and later; the keywords
as a string (Material serializedVersion 6) or ``m_ValidKeywords`` (8). Unity 4's layout (a
mapping of repeated ``data:`` keys) and binary files are refused.
"""

from __future__ import annotations

import math
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
