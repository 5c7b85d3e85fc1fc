"""A texture's values as the model's input reads them, from the image's decoded pixels, and
the packed maps the exports make of them: glTF's metallic-roughness image, Unity's
metallic-gloss map (and its PNG, alpha unassociated).

Blender's order between an Image Texture and a surface input (network.Texture): the image's
colour is decoded to linear where its colour space is sRGB (its Alpha output never is); a
Separate Color node takes the red of that colour, the Alpha output the fourth channel; a
colour on a float input is its luminance, which for the grey maps these are is any channel
(the red is taken); then ``1 - x`` (``invert``), then the Multiply (``scale``)."""

from __future__ import annotations

import numpy as np


def srgb_decode(x):
    """The sRGB curve (IEC 61966-2-1), encoded to linear."""
    x = np.asarray(x, np.float64)
    return np.where(x <= 0.04045, x / 12.92, ((x + 0.055) / 1.055) ** 2.4)


def texture_values(pixels, texture) -> np.ndarray:
    """The float input's value at each texel (h x w, float32) of ``pixels`` (the file's
    values as read, h x w x C) through ``texture`` (network.Texture)."""
    px = np.asarray(pixels, np.float64)
    if px.ndim == 2:
        px = px[..., None]
    if texture.channel == "a":
        value = px[..., 3] if px.shape[-1] >= 4 else np.ones(px.shape[:2])
    else:
        value = px[..., 0]
        if texture.colorspace == "srgb_texture":
            value = srgb_decode(value)
    if texture.invert:
        value = 1.0 - value
    return (value * float(texture.scale)).astype(np.float32)


def _at_size(m, h: int, w: int, value: float = 1.0):
    """A one-channel map sampled at the texel centres of an h x w image (nearest), or the
    constant ``value`` where the map is None."""
    if m is None:
        return np.full((h, w), float(value), np.float32)
    rows = ((np.arange(h) + 0.5) * m.shape[0] / h).astype(int)
    cols = ((np.arange(w) + 0.5) * m.shape[1] / w).astype(int)
    return np.asarray(m, np.float32)[rows][:, cols]


def _size(*maps) -> tuple:
    """The largest height and width of the maps that are not None (1 x 1 for none)."""
    maps = [m for m in maps if m is not None]
    return (max(m.shape[0] for m in maps), max(m.shape[1] for m in maps)) if maps else (1, 1)


def metallic_roughness_pixels(metallic, smoothness, invert: bool):
    """glTF's metallic-roughness image from the model's maps (numpy arrays of one channel,
    or None where the input is a value, carried by the factor): G = roughness = 1 -
    smoothness (the map itself when it fed smoothness through ``1 - x``), B = metallic, R = 1
    (unused). Maps of different sizes are sampled at the larger one's texel centres."""
    h, w = _size(metallic, smoothness)
    rough = _at_size(smoothness, h, w)
    if smoothness is not None and not invert:
        rough = 1.0 - rough
    return np.stack([np.ones((h, w), np.float32), rough, _at_size(metallic, h, w)], axis=-1)


def metallic_gloss_pixels(metallic, smoothness, metallic_value=0.0, smoothness_value=0.5):
    """Unity's metallic-gloss map (float32, h x w x 4): R = G = B = metallic, A = smoothness,
    from the model's maps (one channel each, the values the model reads: ``texture_values``)
    or, where a map is None, the constants. Maps of different sizes are sampled at the larger
    one's texel centres."""
    h, w = _size(metallic, smoothness)
    r = np.clip(_at_size(metallic, h, w, metallic_value), 0.0, 1.0)
    a = np.clip(_at_size(smoothness, h, w, smoothness_value), 0.0, 1.0)
    return np.stack([r, r, r, a], axis=-1).astype(np.float32)


def write_png_rgba_to(tmp, rgba, final) -> None:
    """Write a packed map (core/unity/mat.py ``unity_outputs``' ``(PNG_RGBA, array)``) as an
    8-bit RGBA PNG into ``tmp``, a path staged for ``final`` (core.files.atomic_paths). Its
    alpha is data (smoothness), not coverage: written unassociated (OpenImageIO would
    otherwise divide the colour by it)."""
    from ..errors import UserError
    from ..hdri import oiio

    OIIO = oiio()
    h, w, _ = rgba.shape
    spec = OIIO.ImageSpec(w, h, 4, OIIO.UINT8)
    spec.attribute("oiio:UnassociatedAlpha", 1)
    buf = OIIO.ImageBuf(spec)
    buf.set_pixels(OIIO.ROI(0, w, 0, h, 0, 1, 0, 4), np.clip(rgba, 0, 1).astype(np.float32))
    if not buf.write(str(tmp)):
        raise UserError(f"cannot write {final}: {' '.join(buf.geterror().split())}")
