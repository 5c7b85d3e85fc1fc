"""Chi-square goodness-of-fit tests of a direction sampler against its claimed density, as
Mitsuba 3 (src/python/python/chi2.py) and pbrt-v4 (src/pbrt/bsdfs_test.cpp) do them. Pure
numpy: the samples and the densities come from elsewhere (tests/osl/sampling_probe.osl).

- The sphere is cut into Z_RES x PHI_RES cells of equal solid angle, uniform in (cos theta,
  phi) of the world frame (theta from +Z, phi = atan2(y, x)).
- Observed: the histogram of the valid samples. Invalid ones (those the integrator discards)
  are counted but not binned: the expected counts are the density times the total number of
  samples, so the density's missing mass matches them.
- Expected: the density integrated over each cell, times the number of samples. The density is
  evaluated at midpoints of each cell in (theta, phi), weighted by sin(theta) (so a density
  with a 1 / sin(theta) pole, as the environment's, stays finite), the weights normalised so
  that a constant integrates exactly: SUB_PHI per cell in phi, and rows in equal steps of
  theta over the whole sphere (_row_layout), so that a piecewise-constant density on tiles
  uniform in theta (the environment's) integrates exactly in theta. The EVAL_ROWS x EVAL_COLS
  points form one image (evaluation_directions), one render.
- Cells expected below MIN_EXPECTED are pooled into one (in increasing order, pooling on until
  the pool reaches MIN_EXPECTED, as Mitsuba does); dof = cells - 1; the p-value is the chi-square
  survival function Q(dof / 2, stat / 2), the regularised upper incomplete gamma function
  (Numerical Recipes 6.2: series below a + 1, continued fraction above).
- A family of n tests is held to the Sidak-corrected level 1 - (1 - 0.01) ** (1 / n).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

Z_RES, PHI_RES = 64, 128  # cells: cos(theta) x phi
SUB_PHI = 8  # evaluation points per cell in phi
EVAL_ROWS, EVAL_COLS = 1024, PHI_RES * SUB_PHI  # the evaluation image (one render)
THETA_STEPS = 7 * 128  # evaluation rows: equal steps of theta, 7 per tile row of
# the environment tables (env_importance.TILE_ROWS = 128)
MIN_EXPECTED = 5.0
SIGNIFICANCE = 0.01


# ---------------------------------------------------------------------------------------
# The chi-square distribution


def gammaincc(a: float, x: float) -> float:
    """Q(a, x) = Gamma(a, x) / Gamma(a), a > 0, x >= 0 (Numerical Recipes, gammq)."""
    if a <= 0 or x < 0:
        raise ValueError("gammaincc needs a > 0 and x >= 0")
    if x == 0:
        return 1.0
    log_prefactor = a * math.log(x) - x - math.lgamma(a)
    if x < a + 1.0:
        # P(a, x) = e^-x x^a / Gamma(a + 1) * sum_n x^n / ((a + 1) ... (a + n))
        term = total = 1.0 / a
        ap = a
        for _ in range(100000):
            ap += 1.0
            term *= x / ap
            total += term
            if abs(term) < abs(total) * 1e-15:
                break
        else:
            raise ArithmeticError("gammaincc: the series did not converge")
        return max(0.0, 1.0 - total * math.exp(log_prefactor))
    # Q(a, x) = e^-x x^a / Gamma(a) * 1 / (x + 1 - a - 1 (1 - a) / (x + 3 - a - ...)),
    # by the modified Lentz method
    tiny = 1e-300
    b = x + 1.0 - a
    c = 1.0 / tiny
    d = 1.0 / b
    h = d
    for i in range(1, 100000):
        an = -i * (i - a)
        b += 2.0
        d = an * d + b
        d = tiny if abs(d) < tiny else d
        c = b + an / c
        c = tiny if abs(c) < tiny else c
        d = 1.0 / d
        delta = d * c
        h *= delta
        if abs(delta - 1.0) < 1e-15:
            break
    else:
        raise ArithmeticError("gammaincc: the continued fraction did not converge")
    return math.exp(log_prefactor) * h


def chi2_sf(stat: float, dof: int) -> float:
    """P(X >= stat) for X chi-square with dof degrees of freedom."""
    return gammaincc(dof / 2.0, stat / 2.0)


def sidak(n_tests: int, significance: float = SIGNIFICANCE) -> float:
    """The level each of n tests is held to, so that all pass with probability
    1 - significance when every null hypothesis holds."""
    return 1.0 - (1.0 - significance) ** (1.0 / n_tests)


# ---------------------------------------------------------------------------------------
# Cells and evaluation points


def uniform(rng: np.random.Generator, shape) -> np.ndarray:
    """Uniform float32 numbers in [0, 1), exactly representable (multiples of 2^-24): none
    rounds up to 1."""
    return (np.floor(rng.random(shape) * 2.0**24) / 2.0**24).astype(np.float32)


def cell_of(dirs: np.ndarray) -> np.ndarray:
    """The flat cell index (row-major, Z_RES x PHI_RES) of each direction (..., 3)."""
    d = np.asarray(dirs, dtype=np.float64)
    d = d / np.linalg.norm(d, axis=-1, keepdims=True)
    iz = np.clip(np.floor((d[..., 2] + 1.0) / 2.0 * Z_RES), 0, Z_RES - 1).astype(np.int64)
    phi = np.arctan2(d[..., 1], d[..., 0])
    ip = np.clip(np.floor((phi + np.pi) / (2 * np.pi) * PHI_RES), 0, PHI_RES - 1)
    return iz * PHI_RES + ip.astype(np.int64)


def histogram(dirs: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """Counts of the valid directions per cell, (Z_RES, PHI_RES)."""
    cells = cell_of(np.asarray(dirs)[valid])
    return np.bincount(cells, minlength=Z_RES * PHI_RES).reshape(Z_RES, PHI_RES).astype(float)


def _row_layout():
    """The evaluation image's rows: (z cell of each row, theta of each row, weight of each
    row). The rows are the intervals between THETA_STEPS equal steps of theta over [0, pi]
    and the cells' edges in theta, padded with rows of weight 0 to EVAL_ROWS. So a cell gets
    rows in proportion to its extent in theta (72 at a pole, 9 or 10 at the equator), and
    no row straddles an edge of the environment tables' tile rows, which are equal steps of
    theta too (at any rotation about Z): their density, constant over a tile, integrates
    exactly in theta."""
    z_edges = np.linspace(-1.0, 1.0, Z_RES + 1)
    cell_edges = np.arccos(z_edges)[::-1]  # increasing theta: z from +1 to -1
    steps = np.linspace(0.0, np.pi, THETA_STEPS + 1)
    edges = np.unique(np.concatenate([steps, cell_edges]))
    edges = edges[np.concatenate([[True], np.diff(edges) > 1e-12])]  # one of near-equal edges
    lo, hi = edges[:-1], edges[1:]
    theta = 0.5 * (lo + hi)
    cell = np.clip(Z_RES - np.searchsorted(cell_edges, theta), 0, Z_RES - 1)  # 0 at z = -1
    w = np.sin(theta) * (hi - lo)
    w *= (2.0 / Z_RES) / np.bincount(cell, weights=w, minlength=Z_RES)[cell]  # sums to dz
    pad = EVAL_ROWS - len(theta)
    assert pad >= 0, "more evaluation rows than the image has"
    return (
        np.concatenate([cell, np.zeros(pad, int)]),
        np.concatenate([theta, np.full(pad, np.pi / 2)]),  # (any direction: weight 0)
        np.concatenate([w, np.zeros(pad)]),
    )


def evaluation_directions():
    """(directions (EVAL_ROWS, EVAL_COLS, 3), weights (EVAL_ROWS, EVAL_COLS), solid angle):
    midpoints in (theta, phi) of the cells, SUB_PHI per cell in phi and a number of rows
    per cell in theta (_row_layout); a cell's weights add up to its solid angle,
    4 pi / (Z_RES PHI_RES), so that a constant integrates exactly."""
    _, theta, w_theta = _row_layout()
    phi = -np.pi + (np.arange(EVAL_COLS) + 0.5) * (2 * np.pi / EVAL_COLS)
    dirs = np.stack(
        [
            np.sin(theta)[:, None] * np.cos(phi)[None, :],
            np.sin(theta)[:, None] * np.sin(phi)[None, :],
            np.cos(theta)[:, None] * np.ones_like(phi)[None, :],
        ],
        axis=-1,
    )
    weights = w_theta[:, None] * np.full(EVAL_COLS, 2 * np.pi / EVAL_COLS)[None, :]
    return dirs.astype(np.float32), weights


def integrate(pdf: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """The density (an image of evaluation_directions' points) integrated over each cell,
    (Z_RES, PHI_RES)."""
    cell, _, _ = _row_layout()
    values = np.where(weights > 0, np.asarray(pdf, dtype=np.float64) * weights, 0.0)
    values = values.reshape(EVAL_ROWS, PHI_RES, SUB_PHI)
    values = values.sum(axis=2)
    out = np.zeros((Z_RES, PHI_RES))
    np.add.at(out, cell, values)
    return out


# ---------------------------------------------------------------------------------------
# The test


@dataclass
class Chi2Result:
    stat: float
    dof: int
    p_value: float
    n_samples: int
    n_valid: int
    integral: float  # the density's integral over the sphere
    pooled_cells: int
    zero_cells_hit: int  # samples in cells whose expected count is 0
    worst: str  # the cells that add most to the statistic

    @property
    def valid_fraction(self) -> float:
        return self.n_valid / self.n_samples

    @property
    def valid_stderr(self) -> float:
        f = self.valid_fraction
        return math.sqrt(f * (1.0 - f) / self.n_samples)

    def __str__(self):
        return (
            f"chi2 = {self.stat:.1f}, dof = {self.dof}, p = {self.p_value:.4g}; "
            f"valid {self.valid_fraction:.5f} (+- {self.valid_stderr:.1g}) of "
            f"{self.n_samples}, pdf integral {self.integral:.5f}; "
            f"{self.pooled_cells} cells pooled, {self.zero_cells_hit} samples in "
            f"cells expected 0; largest terms: {self.worst}"
        )


def _cell_name(c: int) -> str:
    i, j = divmod(int(c), PHI_RES)
    z = -1.0 + (i + 0.5) * 2.0 / Z_RES
    phi = math.degrees(-math.pi + (j + 0.5) * 2 * math.pi / PHI_RES)
    return f"(cos theta {z:+.3f}, phi {phi:+.1f} deg)"


# Samples allowed in cells whose density integrates to 0 (a cell's evaluation points can all
# miss a sliver of density at the horizon); beyond this the test fails, as Mitsuba's does.
ZERO_HIT_FRACTION = 1e-5


def chi2_test(observed: np.ndarray, expected: np.ndarray, n_samples: int) -> Chi2Result:
    """observed: counts per cell; expected: counts per cell (density integral x n_samples)."""
    obs = np.asarray(observed, dtype=np.float64).ravel()
    exp = np.asarray(expected, dtype=np.float64).ravel()
    order = np.argsort(exp, kind="stable")
    obs, exp = obs[order], exp[order]
    # pool in increasing order of expectation until the pool reaches MIN_EXPECTED and the
    # next cell does on its own
    low = exp < MIN_EXPECTED
    n_pool = int(low.sum())
    pool_exp, pool_obs = exp[:n_pool].sum(), obs[:n_pool].sum()
    while n_pool > 0 and pool_exp < MIN_EXPECTED and n_pool < len(exp):
        pool_exp += exp[n_pool]
        pool_obs += obs[n_pool]
        n_pool += 1
    terms = (obs[n_pool:] - exp[n_pool:]) ** 2 / exp[n_pool:]
    stat = float(terms.sum())
    dof = len(terms)
    if n_pool > 0 and pool_exp > 0:
        stat += (pool_obs - pool_exp) ** 2 / pool_exp
        dof += 1
    elif pool_obs > 0:
        stat = math.inf  # samples where no density was claimed
    dof -= 1
    worst = np.argsort(terms)[::-1][:3]
    worst_text = ", ".join(
        f"{_cell_name(order[n_pool + t])} {obs[n_pool + t]:.0f} vs {exp[n_pool + t]:.1f}"
        for t in worst
    )
    zero_hit = int(obs[exp == 0].sum())
    if zero_hit > ZERO_HIT_FRACTION * n_samples:
        stat = math.inf  # samples where the density claims none (Mitsuba
        worst_text = f"{zero_hit} samples in cells of density 0; " + worst_text  # fails these)
    p = chi2_sf(stat, dof) if math.isfinite(stat) and dof > 0 else 0.0
    return Chi2Result(
        stat=stat,
        dof=dof,
        p_value=p,
        n_samples=int(n_samples),
        n_valid=int(np.asarray(observed).sum()),
        integral=float(np.asarray(expected).sum() / n_samples),
        pooled_cells=n_pool,
        zero_cells_hit=zero_hit,
        worst=worst_text,
    )
