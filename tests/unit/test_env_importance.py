"""The environment sampling tables: the density the shader divides by is the density of the
draw it makes (checked by simulating the draw), and it follows the HDRI's luminance."""

import numpy as np

from addon.core.env_importance import build_tables, tile_weights


def test_density_is_that_of_the_tabulated_draw():
    rng = np.random.default_rng(0)
    pixels = rng.gamma(0.5, 1.0, size=(32, 64, 3)).astype(np.float32)
    pixels[5, 40] = 5000.0  # a sun
    marginal, conditional, density = build_tables(tile_weights(pixels, rows=8, cols=16), size=1024)
    rows, cols = density.shape
    # simulate the shader's draw: u1 -> row via marginal, u2 -> column via conditional
    n = 400_000
    k1 = np.floor(rng.random(n) * marginal.shape[1]).astype(int)
    r = marginal[0, k1].astype(int)
    k2 = np.floor(rng.random(n) * conditional.shape[1]).astype(int)
    c = conditional[r, k2].astype(int)
    hist = np.bincount(r * cols + c, minlength=rows * cols).reshape(rows, cols) / n
    np.testing.assert_allclose(hist * rows * cols, density, atol=0.05 * density.max())
    assert abs(density.mean() - 1.0) < 1e-6  # a density over [0,1]^2
    assert density[5 // 4, 40 // 4] == density.max()  # the sun's tile is likeliest


def test_uniform_world_gives_solid_angle_density():
    """Uniform radiance: tile probability proportional to solid angle, q = pi/2 sin(theta)."""
    _, _, density = build_tables(tile_weights(np.ones((64, 128, 3), np.float32), rows=16, cols=32))
    theta = (np.arange(density.shape[0]) + 0.5) / density.shape[0] * np.pi
    expected = np.pi / 2 * np.sin(theta)
    np.testing.assert_allclose(density.mean(axis=1), expected, rtol=0.02)


def _tile_luminance(weights):
    """Undo tile_weights' sin(theta) factor and floor: W = L sin + FLOOR a sin with
    a = mean(L sin), so with X = W / sin, a = mean(X sin) / (1 + FLOOR mean(sin))."""
    from addon.core.env_importance import FLOOR

    rows = weights.shape[0]
    sin = np.sin((np.arange(rows) + 0.5) / rows * np.pi)[:, None]
    x = weights / sin
    a = (x * sin).mean() / (1 + FLOOR * sin.mean())
    return x - FLOOR * a


def test_small_and_odd_sized_maps_fill_the_fixed_grid():
    """The grid is 128 x 256 whatever the map: a 16 x 8 map repeats each texel over 16 x 16
    tiles; a 1000 x 500 map (no whole tiles) keeps its mean luminance. A grid built from the
    map's own size (the old rule), or a resampling that lost area, fails."""
    from addon.core.env_importance import TILE_COLS, TILE_ROWS
    from addon.core.model import REC709_LUMINANCE

    y = np.array(REC709_LUMINANCE, np.float32)
    rng = np.random.default_rng(2)
    small = rng.gamma(2.0, 1.0, size=(8, 16, 3)).astype(np.float32)
    w = tile_weights(small)
    assert w.shape == (TILE_ROWS, TILE_COLS)
    expected = np.repeat(np.repeat(small @ y, 16, axis=0), 16, axis=1)
    np.testing.assert_allclose(_tile_luminance(w), expected, rtol=1e-4)
    odd = rng.gamma(2.0, 1.0, size=(500, 1000, 3)).astype(np.float32)
    w = tile_weights(odd)
    assert w.shape == (TILE_ROWS, TILE_COLS)
    np.testing.assert_allclose(_tile_luminance(w).mean(), (odd @ y).mean(), rtol=1e-4)
