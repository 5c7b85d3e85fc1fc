"""Environment importance-sampling tables for the OSL reference integrator.

The HDRI is split into a fixed grid of R x C = 128 x 256 tiles (4 x 4 texels of a 1k map;
larger maps are averaged, smaller ones repeated); tile (r, c) is drawn with a probability
proportional to its mean luminance times its solid angle (sin of the polar angle), floored so
that no tile is impossible. The draw uses two inverse-CDF tables read at texel centres:

- marginal.exr     (M x 1):  entry k -> tile row for u1 in [k/M, (k+1)/M)
- conditional.exr  (M x R):  row r, entry k -> tile column for u2 in [k/M, (k+1)/M)
- pdf.exr          (C x R):  the density q(r, c) of the draw with respect to (s, t)

q is computed from the tables themselves (counts / M), so the density the shader divides by
is exactly that of the draw it makes: the estimator stays unbiased whatever M is
(Pharr, Jakob & Humphreys, PBRT 3rd ed., 13.6.7 and 14.2.4, with tabulated inverses).
In solid angle: p(omega) = q / (2 pi^2 sin(theta)).

The table sizes are fixed so that the shader can name them (its ENV_* constants; a test checks
they agree): OSL cannot ask a texture its size in Blender 5.2 (gettextureinfo crashes Cycles)
and from 5.2 on texture() ignores "closest", so every table is read at its texel centres.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from . import cache
from .hdri import file_hash, load_hdri, write_float_exr
from .latlong import area_resample
from .model import REC709_LUMINANCE

TABLE_SIZE = 4096  # M: resolution of the inverse CDFs (the shader's ENV_TABLE_SIZE)
TILE_ROWS = 128  # R (the shader's ENV_TILE_ROWS)
TILE_COLS = 256  # C (the shader's ENV_TILE_COLS)
FLOOR = 0.01  # every tile gets at least this fraction of the mean weight
VERSION = 3  # 3: a fixed tile grid, whatever the HDRI's size


def tile_weights(pixels: np.ndarray, rows: int = TILE_ROWS, cols: int = TILE_COLS) -> np.ndarray:
    """Mean luminance (Rec. 709) of each tile times sin(theta) at the tile's centre row.
    Tiles that cover whole texels average them; otherwise the texels' areas are shared out
    (latlong.area_resample), so a map smaller than the grid repeats its texels."""
    h, w, _ = pixels.shape
    lum = np.maximum(pixels, 0) @ np.array(REC709_LUMINANCE, dtype=np.float32)
    if h % rows == 0 and w % cols == 0:
        lum = lum.reshape(rows, h // rows, cols, w // cols).mean(axis=(1, 3))
    else:
        lum = area_resample(area_resample(lum, rows, 0, None), cols, 1, None)
    lum = lum.astype(np.float64)
    theta = (np.arange(rows) + 0.5) / rows * np.pi
    weight = lum * np.sin(theta)[:, None]
    mean = weight.mean()
    if mean <= 0:
        weight = np.sin(theta)[:, None] * np.ones((1, cols))
    else:
        weight = weight + FLOOR * mean * np.sin(theta)[:, None]
    return weight


def inverse_cdf(weights: np.ndarray, size: int = TABLE_SIZE) -> np.ndarray:
    """Entry k holds the index i with cdf[i-1] <= (k+0.5)/size < cdf[i]."""
    cdf = np.cumsum(weights, dtype=np.float64)
    cdf /= cdf[-1]
    u = (np.arange(size) + 0.5) / size
    return np.minimum(np.searchsorted(cdf, u, side="right"), len(weights) - 1)


def build_tables(weights: np.ndarray, size: int = TABLE_SIZE):
    """(marginal, conditional, density) as float arrays, density exact for the tables."""
    rows, cols = weights.shape
    marginal = inverse_cdf(weights.sum(axis=1), size)
    conditional = np.stack(
        [
            inverse_cdf(weights[r], size)
            if weights[r].sum() > 0
            else np.arange(size) * cols // size
            for r in range(rows)
        ]
    )
    p_row = np.bincount(marginal, minlength=rows) / size
    p_col = np.stack([np.bincount(conditional[r], minlength=cols) / size for r in range(rows)])
    density = p_row[:, None] * p_col * rows * cols  # w.r.t. (s, t) in [0,1]^2
    return (
        marginal[None, :].astype(np.float32),
        conditional.astype(np.float32),
        density.astype(np.float32),
    )


def tables_for(hdri_path) -> dict:
    """Paths of the three tables for an HDRI, built once and cached by content hash."""
    hdri_path = Path(hdri_path)
    key = f"env-importance-v{VERSION}-{TILE_ROWS}x{TILE_COLS}-{TABLE_SIZE}-{file_hash(hdri_path)}"
    names = ("marginal", "conditional", "pdf")
    folder = cache.lookup(key)
    if folder is None:
        tables = dict(zip(names, build_tables(tile_weights(load_hdri(hdri_path)))))

        def fill(staging: Path):
            for name in names:
                write_float_exr(staging / f"{name}.exr", tables[name])

        folder = cache.build(key, fill)
    return {name: str(folder / f"{name}.exr") for name in names}
