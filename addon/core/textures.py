"""The sphere matrix's textures, as the seed's scene had them: an albedo texture and a
tangent-space normal map on every sphere (``--albedo-texture``, ``--normal-map``,
``--normal-strength``; ``--textured`` takes the pair shipped in addon/data/, made by
scripts/build_seed_textures.py). Checked here, before anything is written: a readable image
of at least 1x1 and at most MAX_SIDE pixels a side, finite texels; a normal map with three
channels whose blue channel mostly points out of the surface (a mean under 0.5 is a warning:
probably not a normal map). Read by OpenImageIO, as every image of the project.

How they map onto a sphere (docs/usage.md "Textures on the sphere matrix"): the UV sphere's
own UVs (u around the equator, v from pole to pole), the texture repeated twice around and
once from pole to pole (``UV_SCALE``), so that a square texture keeps square texels at the
equator; the normal map in OpenGL convention (green up), read by Blender's Normal Map node in
the UV map's tangent space."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .errors import UserError
from .files import DATA_DIR
from .paths import input_file

MAX_SIDE = 8192  # larger images cost memory and time without showing on a matrix's sphere
UV_SCALE = (2.0, 1.0)  # the sphere's UV map scaled: twice around, once pole to pole
SEED_ALBEDO = DATA_DIR / "seed_albedo.png"
SEED_NORMAL = DATA_DIR / "seed_normal.png"
SEED_SOURCE = DATA_DIR / "seed_textures.LICENSE.txt"


@dataclass(frozen=True)
class TextureInfo:
    """What the check read of an image: its size and channels, and any warning."""

    path: str
    width: int
    height: int
    channels: int
    warning: str = ""


def check_texture(text, what: str, normal: bool = False) -> TextureInfo:
    """The image at ``text`` checked as ``what`` ("albedo texture", "normal map"): one
    UserError line for a missing, unreadable, empty, oversized or non-finite image; a normal
    map needs three channels and warns when its blue channel's mean is under 0.5."""
    from .hdri import read_pixels

    path = input_file(text, what, missing=f"{what} not found: {text}; give an image file")

    def header(spec, _OIIO):
        w, h = spec.width, spec.height
        if w < 1 or h < 1:
            raise UserError(f"{what} {path} is {w}x{h} pixels; give an image of at least 1x1")
        if w > MAX_SIDE or h > MAX_SIDE:
            raise UserError(
                f"{what} {path} is {w}x{h} pixels; at most {MAX_SIDE} a side (scale it down)"
            )

    pixels = read_pixels(path, what, header, need=3 if normal else 1)
    h, w, n = pixels.shape
    bad = int(np.count_nonzero(~np.isfinite(pixels)))
    if bad:
        raise UserError(f"{what} holds {bad} NaN/Inf value(s): {path}; repair it first")
    warning = ""
    if normal:
        blue = float(pixels[..., 2].mean())
        if blue < 0.5:
            warning = (
                f"{what} {path} has a mean blue of {blue:.2f} (a tangent-space normal map's "
                "is near 1): it is probably not a normal map"
            )
    return TextureInfo(str(path), w, h, n, warning)


def matrix_textures(albedo: str, normal: str, seed: bool, strength: float) -> tuple:
    """(MatrixSettings fields, warnings) for the chosen textures, each checked
    (``check_texture``); ``seed``: the shipped pair where none is chosen. The command line
    and the Sphere Matrix operator both take them from here."""
    if seed:
        seed_albedo, seed_normal = seed_pair()
        albedo, normal = albedo or seed_albedo, normal or seed_normal
    found, warnings = {"normal_strength": strength}, []
    for key, path, what in (
        ("albedo_texture", albedo, "albedo texture"),
        ("normal_map", normal, "normal map"),
    ):
        if path:
            info = check_texture(path, what, normal=key == "normal_map")
            if info.warning:
                warnings.append(info.warning)
            found[key] = info.path
    return found, warnings


def seed_pair() -> tuple:
    """The shipped albedo texture and normal map (``--textured``)."""
    return str(SEED_ALBEDO), str(SEED_NORMAL)


def texture_hash(path) -> str:
    """A texture's content hash (a task's id depends on it, not on its path)."""
    from .files import sha256

    return sha256(Path(path))


def thumbnail_uri(path, max_side: int = 160) -> str:
    """The image as a small PNG data URI (the report shows the textures a job used without
    copying them): every n-th texel up to ``max_side`` a side, a float image's values
    encoded as sRGB for display; "" when the file no longer reads."""
    import base64

    from .compare import write_png
    from .files import temporary_folder
    from .hdri import read_pixels

    kind = {}

    def header(spec, OIIO):
        kind["float"] = spec.format.basetype in (OIIO.FLOAT, OIIO.HALF, OIIO.DOUBLE)

    try:
        pixels = read_pixels(path, "texture", header, need=1)
    except UserError:
        return ""
    is_float = kind["float"]
    if pixels.shape[2] < 3:
        pixels = np.repeat(pixels[..., :1], 3, axis=2)
    height, width = pixels.shape[:2]
    step = max(1, -(-max(width, height) // max_side))
    pixels = np.nan_to_num(pixels[::step, ::step, :3], nan=0.0, posinf=1.0, neginf=0.0)
    if is_float:
        c = np.clip(pixels, 0.0, 1.0)
        pixels = np.where(c <= 0.0031308, 12.92 * c, 1.055 * c ** (1 / 2.4) - 0.055)
    try:
        with temporary_folder("ctlab-thumb-") as tmp:
            write_png(tmp / "thumb.png", pixels)
            data = (tmp / "thumb.png").read_bytes()
    except (UserError, OSError):
        return ""
    return "data:image/png;base64," + base64.b64encode(data).decode("ascii")
