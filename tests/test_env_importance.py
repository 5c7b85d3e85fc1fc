"""The environment sampling tables: the density the shader divides by is the density of the
draw it makes (checked by simulating the draw), and it follows the HDRI's luminance."""

import numpy as np

from addon.env_importance import build_tables, tile_weights


def test_density_is_that_of_the_tabulated_draw():
    rng = np.random.default_rng(0)
    pixels = rng.gamma(0.5, 1.0, size=(32, 64, 3)).astype(np.float32)
    pixels[5, 40] = 5000.0                                     # a sun
    marginal, conditional, density = build_tables(tile_weights(pixels, tile=4), size=1024)
    rows, cols = density.shape
    # simulate the shader's draw: u1 -> row via marginal, u2 -> column via conditional
    n = 400_000
    k1 = np.floor(rng.random(n) * marginal.shape[1]).astype(int)
    r = marginal[0, k1].astype(int)
    k2 = np.floor(rng.random(n) * conditional.shape[1]).astype(int)
    c = conditional[r, k2].astype(int)
    hist = np.bincount(r * cols + c, minlength=rows * cols).reshape(rows, cols) / n
    np.testing.assert_allclose(hist * rows * cols, density, atol=0.05 * density.max())
    assert abs(density.mean() - 1.0) < 1e-6                    # a density over [0,1]^2
    assert density[5 // 4, 40 // 4] == density.max()          # the sun's tile is likeliest


def test_uniform_world_gives_solid_angle_density():
    """Uniform radiance: tile probability proportional to solid angle, q = pi/2 sin(theta)."""
    _, _, density = build_tables(tile_weights(np.ones((64, 128, 3), np.float32), tile=4))
    theta = (np.arange(density.shape[0]) + 0.5) / density.shape[0] * np.pi
    expected = np.pi / 2 * np.sin(theta)
    np.testing.assert_allclose(density.mean(axis=1), expected, rtol=0.02)
