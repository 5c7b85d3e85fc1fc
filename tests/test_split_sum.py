"""The baked IBL modes in the OSL shader: Unity's formula and the split-sum in a white furnace,
and the split-sum against the reference integration on a mirror."""

import numpy as np

from conftest import render, sphere_pixels
from reference_model import specular_albedo
from addon.compare import ciede2000, read_image, srgb_to_lab
from addon.params import REC709_LUMINANCE

A = (0.9, 0.5, 0.2)
WHITE = dict(grid=(3, 3), size=96, samples=1, sun_strength=0.0, albedo=A, pixel_centres=True)
Y = np.array(REC709_LUMINANCE)


def _pixels(scene, normal, margin_px=2):
    """Per cell: (cell, mask, n.v at each masked pixel)."""
    for cell in scene["cells"]:
        m = sphere_pixels(scene, cell, margin_px)
        yield cell, m, normal[m] @ np.array(scene["to_camera"])


def _colors(cell):
    a, m = np.array(cell["albedo"]), cell["metallic"]
    return 0.04 * (1 - m) + a * m, a * 0.96 * (1 - m)


def test_unity_mode_in_a_white_furnace_is_unitys_formula(tmp_path, uniform_hdri):
    """Every level is 1 and E = pi, so indirect specular is exactly
    surfaceReduction lerp(specColor, grazing, (1 - n.v)^5) and indirect diffuse diffColor."""
    views = ("indirect_specular", "indirect_diffuse", "normal")
    img, scene = render(tmp_path, view=views, ibl="unity", hdri=uniform_hdri, **WHITE)
    for cell, m, nv in _pixels(scene, img["normal"]):
        spec, diff = _colors(cell)
        pr = 1 - cell["smoothness"]
        alpha = max(pr * pr, 0.002)
        grazing = min(1.0, max(0.0, cell["smoothness"] + 1 - 0.96 * (1 - cell["metallic"])))
        t = ((1 - np.clip(nv, 0, 1)) ** 5)[:, None]
        want = (spec * (1 - t) + grazing * t) / (alpha * alpha + 1)
        np.testing.assert_allclose(img["indirect_specular"][m], want, rtol=1e-4, atol=1e-6)
        np.testing.assert_allclose(img["indirect_diffuse"][m], np.broadcast_to(diff, want.shape),
                                   rtol=1e-4, atol=1e-6)


def test_split_sum_in_a_white_furnace_is_the_directional_albedo(tmp_path, uniform_hdri):
    """Every level is 1: indirect specular = specColor A + B, the directional albedo of f_s,
    here against brute-force quadrature of SPEC's f_s; indirect diffuse = diffColor times
    the cosine-weighted mean of Burley's factor (1 for Lambert). 1% covers the bilinear
    lookup between table texels."""
    views = ("indirect_specular", "indirect_diffuse", "normal")
    for g_model in ("cook_torrance", "smith_ggx_correlated"):
        img, scene = render(tmp_path / g_model, view=views, ibl="split_sum", hdri=uniform_hdri,
                            g_model=g_model, **WHITE)
        checked = 0
        for cell, m, nv in _pixels(scene, img["normal"]):
            if cell["smoothness"] == 1.0:
                continue                  # the mirror's lobe is below any quadrature grid
            for mu in (0.9, 0.6, 0.3):
                ring = np.abs(nv - mu) < 0.02
                if ring.sum() < 3:
                    continue
                x = float(np.mean(nv[ring]))
                spec = specular_albedo(x, np.array(cell["albedo"]), cell["metallic"],
                                       cell["smoothness"], g_model=g_model)
                got = img["indirect_specular"][m][ring].mean(axis=0)
                np.testing.assert_allclose(got, spec, rtol=0.01,
                                           err_msg=f"{g_model} {cell['row']},{cell['col']} {mu}")
                _, diff = _colors(cell)
                disney = specular_albedo(x, np.full(3, 1 / 0.96), 0.0, cell["smoothness"],
                                         term="diffuse_brdf")
                np.testing.assert_allclose(img["indirect_diffuse"][m][ring].mean(axis=0),
                                           diff * disney, rtol=0.01, atol=1e-6)
                checked += 1
        assert checked >= 12


def test_split_sum_equals_the_reference_on_mirrors_within_noise(tmp_path):
    """Smoothness 1 (alpha = 0.002): the split-sum's level 0 is the HDRI itself and A + B the
    mirror's Fresnel, so it must agree with the Monte Carlo reference as well as two reference
    renders with different seeds agree with each other (forest.exr, whose sun makes the glints
    noisy). Lambert diffuse: its irradiance split is exact."""
    kw = dict(view="indirect", grid=(2, 3), size=96, samples=64, diffuse_model="lambert",
              albedo=(1.0, 0.766, 0.336))
    ref1, scene = render(tmp_path / "ref1", seed=1, **kw)
    ref2, _ = render(tmp_path / "ref2", seed=2, **kw)
    split, _ = render(tmp_path / "split", ibl="split_sum", **kw)
    disp = {k: read_image(tmp_path / k / "render.png") for k in ("ref1", "ref2", "split")}
    for cell in scene["cells"]:
        if cell["smoothness"] != 1.0:
            continue
        m = sphere_pixels(scene, cell, margin_px=2)
        y1, y2, ys = ((im[m] @ Y).mean() for im in (ref1, ref2, split))
        noise = abs(y2 - y1) / y1
        assert abs(ys - y1) / y1 < 2 * noise + 0.01, (cell["col"], ys, y1, y2)
        de = lambda k: np.median(ciede2000(srgb_to_lab(disp["ref1"][m]), srgb_to_lab(disp[k][m])))  # noqa: E731
        assert de("split") < 1.5 * de("ref2") + 0.2, (cell["col"], de("split"), de("ref2"))
