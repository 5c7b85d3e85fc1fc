"""Direct light against the model's own definition, evaluated independently (docs/model.md,
"Units"): in a black world a coloured Sun of irradiance E gives L = f_r E (n.l) at every sphere
pixel, times pi in Unity's units; and the OSL shader's trace() darkens exactly the pixels whose
ray toward the Sun meets another sphere (its shadow computed here by ray-sphere geometry)."""

import numpy as np
import pytest

from helpers import render, sphere_pixels
from reference_model import terms

SUN = dict(sun_to_light=(-0.3, -0.6, 0.74), sun_strength=2.5, sun_color=(1.0, 0.6, 0.3))
BLACK_WORLD = dict(hdri_strength=0.0, mutual_shadows=False)
# The shadow terminator: the sphere mesh's facets are 360/96 = 3.75 degrees wide, so near
# n.l = 0 the smooth shading normal faces the Sun while the flat facet does not, and the OSL
# shader's shadow ray hits the sphere it leaves (measured: n.l = 0.0165, one pixel a sphere).
# Pixels within one facet's angle of the terminator are left out of the OSL checks.
TERMINATOR = float(np.sin(np.radians(360 / 96)))


def _reference_direct(normal, scene, units):
    """f_r E (n.l) from the rendered normal (its own view) and scene.json's directions."""
    h, w = normal.shape[:2]
    albedo, metallic, smooth = np.zeros((h, w, 3)), np.zeros((h, w)), np.zeros((h, w))
    inside = np.zeros((h, w), dtype=bool)
    for cell in scene["cells"]:
        m = sphere_pixels(scene, cell)
        inside |= m
        albedo[m], metallic[m], smooth[m] = cell["albedo"], cell["metallic"], cell["smoothness"]
    t = terms(
        normal.astype(np.float64),
        scene["to_camera"],
        scene["sun"]["to_light"],
        albedo,
        metallic,
        smooth,
    )
    E = np.array(scene["sun"]["irradiance"])
    direct = (t["specular_brdf"] + t["diffuse_brdf"]) * E * t["NdotL"][..., None]
    spec = t["specular_brdf"] * E * t["NdotL"][..., None]
    k = np.pi if units == "unity" else 1.0
    # float32 error in n.h, amplified by D's conditioning near its peak (test_term_views)
    a2 = t["alpha"] ** 2
    nh = t["NdotH"]
    cond = 4 * nh**2 * np.abs(a2 - 1) / (nh**2 * (a2 - 1) + 1) * 3e-7
    return k * direct, k * spec, cond, inside


@pytest.mark.parametrize(
    "shader,units",
    [("osl", "physical"), ("osl", "unity"), ("nodes", "physical"), ("nodes", "unity")],
)
def test_direct_light_is_f_r_times_E_times_cos(tmp_path, shader, units):
    """A Sun of strength 2.5 and colour (1, 0.6, 0.3) in a black world: a wrong unit factor,
    a grey Sun, a missing n.l or the world leaking in fails by far more than 1e-4."""
    ibl = "reference" if shader == "osl" else "split_sum"
    img, scene = render(
        tmp_path,
        view=("direct", "normal"),
        shader=shader,
        units=units,
        ibl=ibl,
        samples=1,
        pixel_centres=True,
        grid=(3, 3),
        size=96,
        albedo=(0.9, 0.5, 0.2),
        **SUN,
        **BLACK_WORLD,
    )
    assert scene["sun"]["irradiance"] == pytest.approx([2.5, 1.5, 0.75])
    want, spec, cond, inside = _reference_direct(img["normal"], scene, units)
    if shader == "osl":
        inside &= np.abs(img["normal"] @ np.array(scene["sun"]["to_light"])) > TERMINATOR
    got = img["direct"][inside].astype(np.float64)
    want, spec = want[inside], spec[inside]
    tol = np.maximum(np.maximum(1e-4 * np.abs(want), 1e-6), cond[inside][:, None] * spec)
    bad = np.abs(got - want) > tol
    assert not bad.any(), (
        f"{int(bad.sum())} of {bad.size} differ: got {got[bad][:3]} want {want[bad][:3]}"
    )
    assert want.max() > 0.5  # the test sees real light, not zeros


def test_one_sphere_in_anothers_shadow(tmp_path):
    """Two spheres side by side, the Sun low behind the left one: the OSL shader's trace()
    must darken exactly the right sphere's pixels whose ray toward the Sun meets the left
    sphere (checked away from the shadow's edge, where a pixel centre and the mesh's facets
    may disagree), and light the rest as f_r E (n.l)."""
    to_light = np.array([-1.0, 0.15, 0.12])
    to_light /= np.linalg.norm(to_light)
    img, scene = render(
        tmp_path,
        view=("direct", "normal"),
        shader="osl",
        samples=1,
        pixel_centres=True,
        grid=(1, 2),
        size=128,
        albedo=(0.8, 0.8, 0.8),
        sun_to_light=tuple(to_light),
        sun_strength=3.0,
        hdri_strength=0.0,
        mutual_shadows=True,
    )
    want, spec, cond, _ = _reference_direct(img["normal"], scene, "physical")
    left, right = scene["cells"]
    # world geometry (core.settings): spacing 1 m, radius 0.42 m, the grid in the XZ plane
    centre_l, centre_r, radius = np.array([-0.5, 0.0, 0.0]), np.array([0.5, 0.0, 0.0]), 0.42
    m = sphere_pixels(scene, right, margin_px=2)
    n = img["normal"][m].astype(np.float64)
    p = centre_r + radius * n  # the shaded points
    # the ray p + t l meets the left sphere where |p + t l - c|^2 = r^2 for some t > 0
    oc = p - centre_l
    b = oc @ to_light
    c = np.sum(oc * oc, axis=1) - radius**2
    disc = b * b - c
    shadowed = (disc > 0) & (-b - np.sqrt(np.maximum(disc, 0)) > 0)
    # a margin around the shadow's edge: the miss distance within 1.5% of the radius
    closest = np.sqrt(np.maximum(c + radius**2 - b * b, 0))
    clear = np.abs(closest - radius) > 0.015 * radius
    lit = (n @ to_light) > TERMINATOR
    clear &= np.abs(n @ to_light) > TERMINATOR
    got = img["direct"][m]
    assert (shadowed & clear & lit).sum() > 50 and (~shadowed & clear & lit).sum() > 50
    assert np.all(got[shadowed & clear] == 0.0)
    w = want[m][~shadowed & clear]
    np.testing.assert_allclose(got[~shadowed & clear], w, rtol=1e-4, atol=1e-6)
    # the left sphere stands in full light
    ml = sphere_pixels(scene, left, margin_px=2)
    ml &= np.abs(img["normal"] @ to_light) > TERMINATOR
    np.testing.assert_allclose(img["direct"][ml], want[ml], rtol=1e-4, atol=1e-6)
