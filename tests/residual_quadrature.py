"""The residual albedo by quadrature, independently of the node group's tables: a midpoint
grid over the light direction, from docs/model.md's closed forms (tests of the group's and
the OSL shader's Residual Albedo output)."""

import math

import numpy as np

_ALBEDOS = {}  # (G, alpha, n) -> the directional albedos of the G's lobe and Smith's, over ms


def residual_quadrature(g_model, diffuse, energy, mu, pr, spec_color, diff_color, n=480):
    """integral of |f_s,model - f_s,closure| (n.l) dl + integral of |f_d,model - f_Lambert|
    (n.l) dl for each n.v in ``mu`` (the closures: Smith's G, Lambert; with energy
    compensated both lobes scaled by their k_ms, Cycles' Multiscatter GGX for Smith's), by a
    midpoint grid over l in (theta, phi) (not the group's half-vector quadrature), from the
    closed forms of docs/model.md; k_ms from directional albedos integrated on the same grid.
    One colour channel (spec_color, diff_color scalars)."""
    a = max(pr * pr, 0.002)
    th = (np.arange(n) + 0.5) / n * (np.pi / 2)
    ph = (np.arange(2 * n) + 0.5) / (2 * n) * np.pi  # phi in [0, pi], doubled
    T, P = np.meshgrid(th, ph, indexing="ij")
    dw = 2 * np.sin(T) * (np.pi / 2 / n) * (np.pi / (2 * n))
    lx, ly, nl = np.sin(T) * np.cos(P), np.sin(T) * np.sin(P), np.cos(T)

    def lobes(m):
        vx = math.sqrt(max(1 - m * m, 0.0))
        hx, hy, hz = lx + vx, ly, nl + m
        norm = np.sqrt(hx * hx + hy * hy + hz * hz)
        nh, vh = hz / norm, (hx * vx + hz * m) / norm
        d = a * a / (np.pi * (nh * nh * (a * a - 1) + 1) ** 2)
        a2 = a * a
        smith = (
            2
            * nl
            * m
            / (nl * math.sqrt(m * m * (1 - a2) + a2) + m * np.sqrt(nl * nl * (1 - a2) + a2))
        )
        if g_model == "cook_torrance":
            g = np.minimum(1, np.minimum(2 * nh * m / vh, 2 * nh * nl / vh))
        elif g_model == "unity_smith_joint":
            g = 4 * nl * m * 0.5 / (nl * (m * (1 - a) + a) + m * (nl * (1 - a) + a) + 1e-5)
        else:
            g = smith
        f = spec_color + (1 - spec_color) * (1 - vh) ** 5
        base = d / (4 * nl * m)
        fd90 = 0.5 + 2 * vh * vh * pr
        disney = (1 + (fd90 - 1) * (1 - nl) ** 5) * (1 + (fd90 - 1) * (1 - m) ** 5)
        return base * g, base * smith, f, disney

    ms = np.linspace(0.005, 1, 80)
    key = (g_model, a, n)
    if energy != "none" and key not in _ALBEDOS:  # the lobes' directional albedos (no F)
        both = [lobes(m)[:2] for m in ms]
        _ALBEDOS[key] = [np.array([float(np.sum(b[w] * nl * dw)) for b in both]) for w in (0, 1)]

    def k_ms(which):
        if energy == "none":
            return lambda m: 1.0
        E = _ALBEDOS[key][which]
        e_avg = float(np.sum((E * ms)[1:] + (E * ms)[:-1]) * (ms[1] - ms[0]))  # 2 x trapezoids
        f_avg = spec_color + (1 - spec_color) / 21
        f_ms = f_avg * e_avg / (1 - f_avg * (1 - e_avg))
        return lambda m: 1 + f_ms * (1 - np.interp(m, ms, E)) / np.interp(m, ms, E)

    k_g, k_s = k_ms(0), k_ms(1)
    out = []
    for m in np.atleast_1d(mu):
        g, smith, f, disney = lobes(m)
        spec = np.abs(k_g(m) * g - k_s(m) * smith) * f
        diff = diff_color / np.pi * np.abs(disney - 1) if diffuse == "disney" else 0.0
        out.append(float(np.sum((spec + diff) * nl * dw)))
    return np.array(out)
