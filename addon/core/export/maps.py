"""A texture's values as the model's input reads them, from the image's decoded pixels: the
packed maps the exports write (glTF's metallic-roughness image, Unity's metallic-gloss map)
are made from them.

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
