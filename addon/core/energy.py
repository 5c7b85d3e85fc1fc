"""The white furnace: how much energy the shipped shader's specular term keeps.

A uniform world of radiance 1, the Sun off, metallic 1 and albedo 1 (so specColor = 1 and
Schlick's F = 1 exactly): the indirect_specular view of a pixel is then the specular
directional albedo E(v) = integral of D G / (4 (n.l)(n.v)) (n.l) dl, which energy conservation
bounds by 1 (Heitz 2014, "Understanding the Masking-Shadowing Function", section 2). On an
orthographic sphere a pixel at distance d from the centre of a sphere of radius R sees
n.v = sqrt(1 - (d/R)^2), so one render gives E against the view angle for every roughness.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from .hdri import uniform_world
from .model import ModelOptions

ROWS = 6  # smoothness 1, 0.8, ... 0
BINS = 9  # view-angle bins of 10 degrees
WIDTH, HEIGHT = 64, 64 * ROWS


def white_world() -> Path:
    """A uniform world of radiance 1 (kept in the cache)."""
    return uniform_world((1.0, 1.0, 1.0))


def furnace_settings(
    g_model: str, env_samples: int = 4, seed: int = 0, energy: str = "none", ibl: str = "reference"
):
    from .settings import MatrixSettings

    return MatrixSettings(
        rows=ROWS,
        cols=1,
        width=WIDTH,
        height=HEIGHT,
        hdri=str(white_world()),
        sun_strength=0.0,
        metallic=1.0,
        albedo=(1.0, 1.0, 1.0),
        mutual_shadows=False,
        shader="osl",
        model=ModelOptions(
            view="indirect_specular",
            g_model=g_model,
            energy=energy,
            ibl=ibl,
            env_samples=env_samples,
            seed=seed,
        ),
    )


def directional_albedo(image: np.ndarray, scene: dict, bins: int = BINS) -> list:
    """Per sphere: the mean rendered value in view-angle bins (theta_v in [0, 90) degrees),
    with n.v from the pixel's distance to the sphere's centre; pixels within a pixel of the
    silhouette are left out (partly covered)."""
    value = image[..., :3].mean(axis=-1)
    h, w = value.shape
    yy, xx = np.mgrid[0:h, 0:w] + 0.5
    curves = []
    for cell in scene["cells"]:
        cx, cy = cell["center_px"]
        radius = cell["radius_px"]
        d = np.hypot(xx - cx, yy - cy)
        inside = d < radius - 1.0
        theta = np.degrees(np.arcsin(np.clip(d[inside] / radius, 0.0, 1.0)))
        index = np.minimum((theta / (90.0 / bins)).astype(int), bins - 1)
        sums = np.bincount(index, value[inside], bins)
        counts = np.bincount(index, None, bins)
        mean = np.where(counts > 0, sums / np.maximum(counts, 1), np.nan)
        centres = (np.arange(bins) + 0.5) * 90.0 / bins
        curves.append(
            {
                "smoothness": cell["smoothness"],
                "theta_deg": centres.tolist(),
                "albedo": [None if math.isnan(x) else float(x) for x in mean],
                "pixels": counts.astype(int).tolist(),
            }
        )
    return curves


def mean_albedo(curve: dict) -> float:
    """The curve's average over view angles, weighted by solid angle of view directions
    (sin theta cos theta, the cosine-weighted hemispherical average)."""
    t = np.radians(np.array(curve["theta_deg"]))
    e = np.array([np.nan if x is None else x for x in curve["albedo"]], dtype=float)
    w = np.sin(t) * np.cos(t)
    ok = np.isfinite(e)
    return float(np.sum(e[ok] * w[ok]) / np.sum(w[ok]))
