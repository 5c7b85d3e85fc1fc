"""The export's names and numbers, for every format: a material's MaterialX element, USD
prim, .mtlx file and glTF packed image (``export_names``: all of a file's materials at once,
unique without regard to case), a texture's file name (``texture_name``), a user's text as
UTF-8 (``utf8_text``) and a float as the documents write it (``fmt_float``)."""

from __future__ import annotations

import re
from dataclasses import dataclass

from ..paths import safe_name

_INVALID = re.compile(r"[^A-Za-z0-9_]")
MAX_IDENT = 128  # characters of a MaterialX element or USD prim name, before a "_N" suffix
MAX_STEM = 64  # bytes of a file name made from a user's name (core.paths.safe_name), ASCII
MR_SUFFIX = "_metallic_roughness.png"  # glTF's packed image: textures/<stem>_metallic_roughness.png
TEXTURES = "textures/"
# A texture's own extension is kept when it is one of these (letters and digits, short);
# any other (240 characters, undecodable bytes, spaces) is replaced by the image's format's.
_EXTENSION = re.compile(r"\.[A-Za-z0-9]{1,10}", re.ASCII)


def _fold(name: str) -> str:
    """A name as a case-insensitive file system compares it (macOS, Windows)."""
    return name.casefold()


def valid_name(text: str, used: set) -> str:
    """A MaterialX element name and USD prim name from ``text`` (ASCII letters, digits and
    underscores, not starting with a digit, at most MAX_IDENT characters before a suffix),
    unique among ``used`` (which it joins) compared without case, as a case-insensitive file
    system compares the file names made from it: ``used`` holds folded names."""
    base = _INVALID.sub("_", str(text))[:MAX_IDENT] or "material"
    if base[0].isdigit():
        base = "_" + base
    name, i = base, 1
    while _fold(name) in used:
        i += 1
        name = f"{base}_{i}"
    used.add(_fold(name))
    return name


def utf8_text(text) -> str:
    """``text`` as valid UTF-8 (a name read from a non-UTF-8 file name holds surrogates:
    its undecodable bytes become U+FFFD), for a document that is encoded as UTF-8."""
    text = str(text)
    try:
        text.encode("utf-8")
        return text
    except UnicodeEncodeError:
        try:
            return text.encode("utf-8", "surrogateescape").decode("utf-8", "replace")
        except UnicodeEncodeError:
            return text.encode("utf-8", "replace").decode("utf-8")


def file_stem(text, default: str) -> str:
    """A file name stem from a user's name: ASCII letters, digits and underscores, at most
    MAX_STEM bytes (``core.paths.safe_name``, then ``valid_name``'s characters)."""
    base = _INVALID.sub("_", safe_name(utf8_text(text), default, limit=MAX_STEM))
    if base[0].isdigit():
        base = "_" + base
    return base[:MAX_STEM]


def texture_name(stem_text, extension: str, fallback: str, used: set) -> str:
    """A texture's name inside the export folder, ``textures/NAME``, from its file's stem
    (or the image's name) and extension: a bounded ASCII file name (at most MAX_STEM bytes of
    stem, a suffix and an extension of at most 11), unique among ``used`` (folded names,
    which it joins). An extension that is not short letters and digits (undecodable bytes,
    hundreds of characters) gives way to ``fallback`` (the image format's)."""
    ext = extension if _EXTENSION.fullmatch(extension or "") else fallback
    if not _EXTENSION.fullmatch(ext or ""):
        ext = ".png"
    stem = file_stem(stem_text, "texture")
    name, i = f"{TEXTURES}{stem}{ext}", 1
    while _fold(name) in used:
        i += 1
        name = f"{TEXTURES}{stem}_{i}{ext}"
    used.add(_fold(name))
    return name


@dataclass(frozen=True)
class ExportNames:
    """A material's names in the export, unique among the materials exported together:
    ``ident`` its MaterialX element and USD prim name, ``mtlx`` its .mtlx file,
    ``metallic_roughness`` glTF's packed image (textures/NAME; None when the material has no
    metallic or smoothness map)."""

    ident: str
    mtlx: str
    metallic_roughness: str | None


def export_names(materials) -> list:
    """Every material's names (ExportNames, in the list's order), made at once so that no two
    materials share one: materials whose names sanitise alike ("Gold/1" and "Gold?1"), differ
    by case ("Gold", "gold": one file on a case-insensitive file system) or share a name (a
    local material and one linked from a library) get ``_2``, ``_3``, … in order. glTF's
    packed images also avoid every texture file the materials reference. Deterministic: the
    same list gives the same names."""
    materials = list(materials)
    textures = {_fold(t.file) for m in materials for t in m.textures.values()}
    idents, stems, out = set(), set(), []
    for mat in materials:
        ident = valid_name(mat.name, idents)
        base = file_stem(mat.name, "material")
        stem, i = base, 1
        while _fold(stem) in stems or _fold(f"{TEXTURES}{stem}{MR_SUFFIX}") in textures:
            i += 1
            stem = f"{base}_{i}"
        stems.add(_fold(stem))
        packed = "metallic" in mat.textures or "smoothness" in mat.textures
        out.append(
            ExportNames(ident, f"{stem}.mtlx", f"{TEXTURES}{stem}{MR_SUFFIX}" if packed else None)
        )
    return out


def fmt_float(x: float) -> str:
    """A number in 9 significant digits (a float32 reads back exactly)."""
    return f"{float(x):.9g}"
