"""A study, not part of the product: would albedo scaling replace the node group's world
correction (the five pre-filtered chains that cost 1.3x Principled's render time,
bench/scene_cost.py)?

Albedo scaling weights the closures Cycles path traces (GGX with Smith's G, Lambert) by the
ratio of the model's directional albedo to theirs, per colour channel,
w_s(n.v) = A_model(n.v) / A_Smith(n.v) and w_d = A_Disney(n.v) / A_Lambert, so that under a
uniform world the closures reflect what the model reflects, with no emission at all (and the
world's shadows traced, which the split-sum emission ignores). Under any other world its error
is the difference of the lobes' shapes. This measures it where tests/slow/
test_scene_transport_nodes.py measures the split-sum correction: spheres of albedo 0.8 under
the same smooth sky (tests/slow/test_scene_transport.py soft_sky, written here as its
formula), seen orthographically, each pixel's radiance integrated over 60,000 Fibonacci
directions with the model of tests/reference_model.py (written from docs/model.md), energy
none; the mean CIEDE2000 over the sphere (inside 0.9 of its radius) of the display values
(sRGB, 8 bits) against the model's, for the closures alone and albedo-scaled.

    ./scripts/dev.sh albedo_study     # about 6 min on 2 cores

Result (2026-12-04; the split-sum correction's figures in that test, at 1024 samples, in
brackets): Cook-Torrance G on metal at smoothness 0: closures alone 4.94, albedo-scaled 1.82
(0.68); at 0.5: 0.92, 0.95 (0.58); Disney's diffuse on the rough dielectric with the
Cook-Torrance G: 1.45, 0.80 (0.11-0.39); Unity's G on metal at 0.5: 1.40, 0.33 (0.45). Albedo
scaling fails the 0.5 bound where the Cook-Torrance lobe's shape differs from Smith's; it
does not replace the split-sum correction.
"""

import os
import sys

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path[:0] = [ROOT, os.path.join(ROOT, "tests")]
from addon.core.compare import ciede2000, srgb_to_lab  # noqa: E402
from reference_model import terms  # noqa: E402

DIRECTIONS, PIXELS, ALBEDO = 60000, 24, 0.8
SMITH = ("smith_ggx_correlated", "lambert")


def soft_sky(d):
    """tests/slow/test_scene_transport.py soft_sky as a function of the direction."""
    sky = np.where(
        d[..., 2:3] > 0,
        (0.35 + 0.65 * d[..., 2:3]) * np.array([0.55, 0.75, 1.0]) + 0.3,
        np.array([0.12, 0.08, 0.05]),
    )
    lobe = np.clip(d @ np.array([0.6, -0.6, 0.52]), 0, 1) ** 8 * 6.0
    return sky + lobe[..., None] * np.array([1.0, 0.8, 0.55])


def fibonacci(n):
    i = np.arange(n) + 0.5
    z = 1 - 2 * i / n
    r = np.sqrt(1 - z * z)
    phi = np.pi * (1 + 5**0.5) * i
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], -1), 4 * np.pi / n


DIRS, WEIGHT = fibonacci(DIRECTIONS)
SKY, WHITE = soft_sky(DIRS), np.ones((DIRECTIONS, 3))
VIEW = np.array([0.0, -1.0, 0.0])


def sphere_normals():
    g = (np.arange(PIXELS) + 0.5) / PIXELS * 2 - 1
    x, z = np.meshgrid(g, g)
    inside = x**2 + z**2 < 0.81
    x, z = x[inside], z[inside]
    return np.stack([x, -np.sqrt(1 - x**2 - z**2), z], -1)


def reflected(n, metallic, smoothness, g_model, diffuse, light):
    """(specular, diffuse) radiance toward VIEW at normal n: sum of f (n.l) L w."""
    count = len(DIRS)
    t = terms(
        np.broadcast_to(n, DIRS.shape),
        VIEW,
        DIRS,
        np.full(DIRS.shape, ALBEDO),
        np.full(count, metallic),
        np.full(count, smoothness),
        g_model,
        diffuse,
    )
    cos = t["NdotL"][..., None] * light * WEIGHT
    return (t["specular_brdf"] * cos).sum(0), (t["diffuse_brdf"] * cos).sum(0)


def display(radiance):
    c = np.clip(radiance, 0, 1)
    return np.round(np.where(c <= 0.0031308, 12.92 * c, 1.055 * c ** (1 / 2.4) - 0.055) * 255) / 255


def mean_delta_e(a, b):
    return float(ciede2000(srgb_to_lab(display(a)), srgb_to_lab(display(b))).mean())


def sphere(metallic, smoothness, g_model, diffuse):
    model, alone, scaled = [], [], []
    for n in sphere_normals():
        sm, dm = reflected(n, metallic, smoothness, g_model, diffuse, SKY)
        ss, ds = reflected(n, metallic, smoothness, *SMITH, SKY)
        am, adm = reflected(n, metallic, smoothness, g_model, diffuse, WHITE)
        a_s, a_d = reflected(n, metallic, smoothness, *SMITH, WHITE)
        w_s = np.where(a_s > 1e-9, am / np.maximum(a_s, 1e-9), 1.0)
        w_d = np.where(a_d > 1e-9, adm / np.maximum(a_d, 1e-9), 1.0)
        model.append(sm + dm)
        alone.append(ss + ds)
        scaled.append(w_s * ss + w_d * ds)
    model, alone, scaled = map(np.array, (model, alone, scaled))
    return mean_delta_e(model, alone), mean_delta_e(model, scaled)


def main():
    print("| G | diffuse | metallic | smoothness | closures alone | albedo-scaled |")
    print("|---|---|---|---|---|---|")
    for g_model in ("cook_torrance", "unity_smith_joint"):
        for metallic, smoothness in ((1.0, 0.0), (1.0, 0.5), (0.0, 0.0), (0.0, 0.5)):
            diffuse = "disney" if metallic == 0 else "lambert"
            alone, scaled = sphere(metallic, smoothness, g_model, diffuse)
            print(
                f"| {g_model} | {diffuse} | {metallic} | {smoothness} | {alone:.2f} | "
                f"{scaled:.2f} |",
                flush=True,
            )
    alone, scaled = sphere(0.0, 1.0, "smith_ggx_correlated", "disney")
    print(f"| smith_ggx_correlated | disney | 0.0 | 1.0 | {alone:.2f} | {scaled:.2f} |")


if __name__ == "__main__":
    main()
