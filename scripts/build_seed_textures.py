"""Write the sphere matrix's shipped texture pair (addon/data/seed_albedo.png and
seed_normal.png, read by ``ctlab matrix --textured``; addon/core/textures.py): a running-bond
brick wall, made here from numbers alone, so that the pair is the project's own work and
dedicated to the public domain (CC0 1.0; addon/data/seed_textures.LICENSE.txt).

- Bricks of 4 x 8 per tile (staggered every other row), mortar 1/16 of a brick's height.
- Albedo (sRGB PNG): each brick a red-brown drawn from a fixed seed, a low-frequency mottle
  (the sum of a few sines), mortar a light grey.
- Height: bricks raised by 1, their edges bevelled over 1/10 of a brick's height, mortar at 0,
  a small mottle on the bricks' faces; the normal map (OpenGL convention, green up, as
  Blender's Normal Map node reads it) is n = normalize(-dh/du, -dh/dv, 1) / 2 + 1/2 with v up
  (image rows run down), by central differences that wrap (the texture tiles).

Run it with a bpy Python; the output is the same bytes on every run with the same Blender:

    ./scripts/dev.sh build_seed_textures
"""

import os
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

import bpy  # noqa: E402
import numpy as np  # noqa: E402

bpy.utils.expose_bundled_modules()

from addon.core.compare import write_png  # noqa: E402
from addon.core.textures import SEED_ALBEDO, SEED_NORMAL  # noqa: E402

SIZE = 256  # pixels a side: a matrix sphere is at most a few hundred pixels across
ROWS, COLS = 8, 4  # bricks per tile
MORTAR = 1 / 16  # of a brick's height
BEVEL = 1 / 10  # of a brick's height
RELIEF = 2.0  # height in texels of a brick's face above the mortar (the normals' slope)


def _srgb(linear):
    return np.where(linear <= 0.0031308, 12.92 * linear, 1.055 * linear ** (1 / 2.4) - 0.055)


def brick_fields(size: int = SIZE):
    """(brick index, distance to the brick's edge in brick heights, inside) per texel."""
    y, x = (np.mgrid[0:size, 0:size] + 0.5) / size
    row = np.floor(y * ROWS).astype(int)
    shifted = x * COLS + 0.5 * (row % 2)
    col = np.floor(shifted).astype(int) % COLS
    fy = y * ROWS - np.floor(y * ROWS)  # 0..1 within the brick's height
    fx = shifted - np.floor(shifted)
    aspect = ROWS / COLS  # a brick's width in brick heights
    edge = np.minimum(np.minimum(fy, 1 - fy), np.minimum(fx, 1 - fx) * aspect)
    inside = edge > MORTAR / 2
    return row * COLS + col, edge - MORTAR / 2, inside, x, y


def textures(size: int = SIZE):
    """(albedo sRGB 0..1, normal map 0..1), each (size, size, 3)."""
    brick, edge, inside, x, y = brick_fields(size)
    rng = np.random.default_rng(2026)
    tint = rng.uniform(0.0, 1.0, (ROWS * COLS, 3))
    base = np.array([0.42, 0.13, 0.07]) * (0.75 + 0.5 * tint[:, :1]) + 0.05 * (tint - 0.5)
    mottle = 0.08 * (
        np.sin(2 * np.pi * (3 * x + 5 * y)) * np.sin(2 * np.pi * (7 * x - 2 * y))
        + 0.5 * np.sin(2 * np.pi * (11 * x + 13 * y))
    )
    linear = np.where(
        inside[..., None],
        np.clip(base[brick] * (1 + mottle[..., None]), 0, 1),
        np.array([0.55, 0.53, 0.50]),
    )
    height = np.where(inside, np.clip(edge / BEVEL, 0, 1) * (1 + 0.15 * mottle), 0.0) * RELIEF
    du = (np.roll(height, -1, axis=1) - np.roll(height, 1, axis=1)) / 2
    dv = -(np.roll(height, -1, axis=0) - np.roll(height, 1, axis=0)) / 2  # v up, rows down
    n = np.stack([-du, -dv, np.ones_like(height)], axis=-1)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    return _srgb(linear), n * 0.5 + 0.5


def main() -> None:
    albedo, normal = textures()
    write_png(SEED_ALBEDO, albedo)
    write_png(SEED_NORMAL, normal)
    print(f"wrote {SEED_ALBEDO} and {SEED_NORMAL}")


if __name__ == "__main__":
    main()
