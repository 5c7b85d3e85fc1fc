"""Reading and checking an equirectangular HDRI with OpenImageIO (Blender's bundled module)."""

from __future__ import annotations

import functools
from pathlib import Path

import numpy as np

from .errors import UserError
from .files import atomic_path, public, sha256


def oiio():
    """Blender's bundled OpenImageIO (never the PyPI wheel: it breaks OSL compilation). The
    Blender layer makes it importable (bpy.utils.expose_bundled_modules, addon/blender)."""
    try:
        import OpenImageIO
    except ImportError:
        raise UserError(
            "Blender's bundled OpenImageIO Python module cannot be imported; "
            "Cook-Torrance Lab needs Blender 4.5 or newer (as an application or "
            "the bpy module, with its bundled modules exposed)"
        ) from None
    return OpenImageIO


def file_hash(path: Path) -> str:
    """Content hash of a file (the cache key of everything derived from it)."""
    return sha256(path)[:24]


def read_hdri(path, repair: bool = False):
    """The HDRI as a float32 array (height, width, 3), scene-linear and read-only, and the
    number of NaN/Inf pixels that were set to 0 (only with ``repair``; otherwise they raise).
    A file is decoded once while its size and modification time stay the same.

    Raises UserError when the file is missing or unreadable, not floating point, has fewer
    than 3 channels or is not 2:1 equirectangular."""
    from .paths import input_file

    path = input_file(
        path,
        "HDRI",
        missing=f"HDRI not found: {path} (give an existing equirectangular .exr or .hdr file)",
    )  # the one path gate
    st = path.stat()
    pixels, count = _decode(str(path), st.st_size, st.st_mtime_ns)
    if count and not repair:
        raise UserError(
            f"HDRI holds {count} NaN/Inf pixel(s): {path}; no job uses such an "
            "image (a render would carry them): repair it first, e.g. oiiotool "
            "IN --fixnan black -o OUT"
        )
    return pixels, count


def read_pixels(path, what: str = "image", check=None, need: int = 3, keep: int = 3) -> np.ndarray:
    """An image file's first ``keep`` channels (at most) as float32 (height, width, k), read
    whole: an unreadable, truncated or corrupt file is a UserError naming it as ``what``,
    never zeros. ``check(spec, OIIO)`` may refuse the file from its header before the pixels
    are read. ``need``: the fewest channels taken (an image of fewer than three then gives
    its own count, (height, width, 1 or 2)). The values are the file's: colour never
    multiplied by alpha (OpenImageIO would associate a PNG's), as Blender's Channel Packed
    alpha reads them."""
    path = Path(path)
    OIIO = oiio()
    config = OIIO.ImageSpec()
    config.attribute("oiio:UnassociatedAlpha", 1)
    inp = OIIO.ImageInput.open(str(path), config)
    if inp is None:
        raise UserError(
            f"{what} unreadable: {path} ({OIIO.geterror().strip() or 'unknown format'})"
        )
    try:
        spec = inp.spec()
        if check is not None:
            check(spec, OIIO)
        if spec.nchannels < need:
            raise UserError(
                f"{what} has {spec.nchannels} channel(s): {path}; an RGB image is needed"
            )
        k = min(spec.nchannels, keep)
        pixels = inp.read_image(0, 0, 0, k, OIIO.FLOAT)
        failed = inp.has_error
        detail = inp.geterror().strip() if failed else ""
    finally:
        inp.close()
    if pixels is None or failed:
        raise UserError(
            f"{what} unreadable: {path} (the pixel data is corrupt or truncated"
            + (f": {detail}" if detail else "")
            + ")"
        )
    return np.asarray(pixels, dtype=np.float32).reshape(spec.height, spec.width, k)


def _equirectangular_float(path):
    def check(spec, OIIO):
        if spec.format.basetype not in (OIIO.FLOAT, OIIO.HALF, OIIO.DOUBLE):
            raise UserError(
                f"HDRI is not floating point: {path} has {spec.format} pixels; "
                "use a scene-linear float image (.exr or .hdr)"
            )
        if spec.nchannels >= 3 and spec.width != 2 * spec.height:
            raise UserError(f"HDRI is {spec.width}x{spec.height}, not 2:1 equirectangular: {path}")

    return check


@functools.lru_cache(maxsize=2)
def _decode(path: str, size: int, mtime_ns: int):
    """The pixels with NaN/Inf texels set to 0, and how many there were."""
    pixels = read_pixels(path, "HDRI", _equirectangular_float(path))
    bad = ~np.isfinite(pixels)
    count = int(bad.any(axis=2).sum())
    if count:
        pixels = np.where(bad.any(axis=2, keepdims=True), np.float32(0), pixels)
    pixels.setflags(write=False)
    # Small negative texels are compression noise (7 of Blender's 8 bundled HDRIs have some);
    # Blender renders them as they are, and so do we. Importance weights clamp them to 0.
    return pixels, count


def image_width(path) -> int:
    """An image's width in texels, from its header (0 when it cannot be read)."""
    OIIO = oiio()
    inp = OIIO.ImageInput.open(str(path))
    if inp is None:
        return 0
    try:
        return int(inp.spec().width)
    finally:
        inp.close()


def load_hdri(path) -> np.ndarray:
    """The HDRI's pixels (read_hdri), refusing NaN/Inf: a render would carry them."""
    return read_hdri(path)[0]


def write_float_exr(path: Path, pixels: np.ndarray) -> None:
    """Write a float32 EXR whole or not at all (temporary name, then rename)."""
    OIIO = oiio()
    pixels = np.ascontiguousarray(pixels, dtype=np.float32)
    if pixels.ndim == 2:
        pixels = pixels[:, :, None]
    h, w, c = pixels.shape
    spec = OIIO.ImageSpec(w, h, c, OIIO.FLOAT)
    spec.attribute("compression", "zip")
    with atomic_path(path) as tmp:
        out = OIIO.ImageOutput.create(str(tmp))
        if out is None or not out.open(str(tmp), spec):
            raise UserError(f"cannot write {public(path)}: {OIIO.geterror().strip()}")
        ok = out.write_image(pixels)
        out.close()
        if not ok:
            raise UserError(f"cannot write {public(path)}: {OIIO.geterror().strip()}")


def uniform_world(colour) -> Path:
    """A small equirectangular image of one colour (a world without an image, the white
    furnace), kept in the cache."""
    from . import cache

    colour = tuple(float(c) for c in colour[:3])
    key = "uniform-%.6g-%.6g-%.6g" % colour
    folder = cache.cached(
        key,
        lambda stage: write_float_exr(
            stage / "world.exr", np.broadcast_to(np.float32(colour), (8, 16, 3)).copy()
        ),
    )
    return folder / "world.exr"
