"""The baked IBL modes in the OSL shader: Unity's formula and the split-sum in a white furnace,
and the split-sum against the reference integration on a mirror."""

import numpy as np

from helpers import render, sphere_pixels
from reference_model import specular_albedo
from addon.core.compare import ciede2000, read_image, srgb_to_lab
from addon.core.model import G_MODELS, REC709_LUMINANCE

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
        np.testing.assert_allclose(
            img["indirect_diffuse"][m], np.broadcast_to(diff, want.shape), rtol=1e-4, atol=1e-6
        )


def test_split_sum_in_a_white_furnace_is_the_directional_albedo(tmp_path, uniform_hdri):
    """Every level is 1: indirect specular = specColor A + B, the directional albedo of f_s,
    here against brute-force quadrature of the model's f_s; indirect diffuse = diffColor times
    the cosine-weighted mean of Burley's factor (1 for Lambert). 1% covers the bilinear
    lookup between table texels."""
    views = ("indirect_specular", "indirect_diffuse", "normal")
    for g_model in G_MODELS:
        img, scene = render(
            tmp_path / g_model,
            view=views,
            ibl="split_sum",
            hdri=uniform_hdri,
            g_model=g_model,
            **WHITE,
        )
        checked = 0
        for cell, m, nv in _pixels(scene, img["normal"]):
            if cell["smoothness"] == 1.0:
                continue  # the mirror's lobe is below any quadrature grid
            for mu in (0.9, 0.6, 0.3):
                ring = np.abs(nv - mu) < 0.02
                if ring.sum() < 3:
                    continue
                x = float(np.mean(nv[ring]))
                spec = specular_albedo(
                    x,
                    np.array(cell["albedo"]),
                    cell["metallic"],
                    cell["smoothness"],
                    g_model=g_model,
                )
                got = img["indirect_specular"][m][ring].mean(axis=0)
                np.testing.assert_allclose(
                    got, spec, rtol=0.01, err_msg=f"{g_model} {cell['row']},{cell['col']} {mu}"
                )
                _, diff = _colors(cell)
                disney = specular_albedo(
                    x, np.full(3, 1 / 0.96), 0.0, cell["smoothness"], term="diffuse_brdf"
                )
                np.testing.assert_allclose(
                    img["indirect_diffuse"][m][ring].mean(axis=0),
                    diff * disney,
                    rtol=0.01,
                    atol=1e-6,
                )
                checked += 1
        assert checked >= 12


def test_split_sum_equals_the_reference_on_mirrors_within_noise(tmp_path):
    """Smoothness 1 (alpha = 0.002): the split-sum's level 0 is the HDRI itself and A + B the
    mirror's Fresnel, so it must agree with the Monte Carlo reference up to noise (forest.exr,
    whose sun makes the glints noisy). Lambert diffuse: its irradiance split is exact.

    The noise is the sun's glint: it covers about a pixel, so the pixel-jitter pattern
    (Cycles' seed) alone moves a mirror sphere's mean luminance by up to 4% (metallic 0.5,
    seeds 0-3, bpy 5.0: split-sum 0.833, 0.815, 0.789, 0.788, reference 0.833, 0.798, 0.797,
    0.782; bpy 4.5: 0.791, 0.806, 0.814, 0.810 and 0.793, 0.804, 0.819, 0.825). At pixel
    centres, with no jitter, 4.5 and 5.0 render identical values. So both are averaged over
    the same two seeds and must agree within 4%, where the per-seed differences reach 2%;
    level 0 scaled by 0.9 (the mutation tried) moved the half-metal mirror by 4.8% and failed.
    (A bound from two reference seeds' own difference, the test's earlier form, failed on
    5.0 and 5.1 where those two seeds happened to agree within 0.1%.) The median per-pixel
    CIEDE2000, which ignores the few glint pixels, is held to the reference's own."""
    kw = dict(
        view="indirect",
        grid=(2, 3),
        size=96,
        samples=64,
        diffuse_model="lambert",
        albedo=(1.0, 0.766, 0.336),
    )
    imgs = {}
    for seed in (1, 2):
        imgs["ref", seed], scene = render(tmp_path / f"ref{seed}", seed=seed, **kw)
        imgs["split", seed], _ = render(tmp_path / f"split{seed}", ibl="split_sum", seed=seed, **kw)
    disp = {k: read_image(tmp_path / k / "render.png") for k in ("ref1", "ref2", "split1")}
    checked = 0
    for cell in scene["cells"]:
        if cell["smoothness"] != 1.0:
            continue
        m = sphere_pixels(scene, cell, margin_px=2)
        y = {k: (im[m] @ Y).mean() for k, im in imgs.items()}
        y_ref = (y["ref", 1] + y["ref", 2]) / 2
        y_split = (y["split", 1] + y["split", 2]) / 2
        assert abs(y_split - y_ref) / y_ref < 0.04, (cell["col"], y)

        def de(k, m=m):
            return np.median(ciede2000(srgb_to_lab(disp["ref1"][m]), srgb_to_lab(disp[k][m])))

        assert de("split1") < 1.5 * de("ref2") + 0.2, (cell["col"], de("split1"), de("ref2"))
        checked += 1
    assert checked == 3


def test_the_world_strength_scales_every_indirect_mode_exactly(tmp_path):
    """HDRI Strength multiplies the world's radiance: at pixel centres, with the same seed, the
    split-sum, Unity's mode and the reference integration scale by 2.5 to float precision
    (measured within 2.3e-4 relative: bpy 4.5's OpenImageIO filtering and the reference's
    sums round the scaled and the unscaled renders differently at a few pixels). On 5.2 a
    pixel-centre render is not quite repeatable: the same render twice differs at one or two
    pixels in 3072 by up to 0.3% (seen in every mode, one run in two), so those are allowed
    within 1%. A strength applied twice, or not at all, to any lookup is off by 150% or 60%."""
    kw = dict(
        view="indirect", grid=(2, 2), size=48, samples=1, pixel_centres=True, sun_strength=0.0
    )
    for ibl in ("split_sum", "unity", "reference"):
        one, scene = render(tmp_path / f"{ibl}-1", ibl=ibl, hdri_strength=1.0, **kw)
        more, _ = render(tmp_path / f"{ibl}-2.5", ibl=ibl, hdri_strength=2.5, **kw)
        m = np.zeros(one.shape[:2], dtype=bool)
        for cell in scene["cells"]:
            m |= sphere_pixels(scene, cell)
        np.testing.assert_allclose(more[m], 2.5 * one[m], rtol=1e-2, atol=1e-7, err_msg=ibl)
        off = np.abs(more[m] - 2.5 * one[m]) > 1e-3 * np.abs(2.5 * one[m]) + 1e-7
        assert off.mean() < 2e-3, (ibl, int(off.sum()))
        assert one[m].mean() > 0.05


def test_the_dominant_direction_brings_rough_metals_toward_the_reference(tmp_path):
    """--ibl split_sum_corrected (the dominant direction of Lagarde and de Rousiers 2014, with t
    the model's lobe centroid): under forest.exr, the rough metal's indirect light, which the
    plain split-sum darkens by about 20% against the reference integration, comes within 5%,
    and every sphere within 6% (with Frostbite's fit for Smith's G instead of this G's t, the
    rough Cook-Torrance metal overshot by 8%)."""
    common = dict(grid=(3, 3), size=96, samples=32, view="indirect")
    imgs = {}
    for ibl in ("reference", "split_sum", "split_sum_corrected"):
        imgs[ibl], scene = render(tmp_path / ibl, ibl=ibl, **common)
    lum = np.array(REC709_LUMINANCE)
    for cell in scene["cells"]:
        m = sphere_pixels(scene, cell)
        ref, plain, corrected = (
            (imgs[k][m][:, :3] @ lum).mean()
            for k in ("reference", "split_sum", "split_sum_corrected")
        )
        assert abs(corrected / ref - 1) < 0.06, (cell["row"], cell["col"], corrected / ref)
        if cell["metallic"] == 1.0 and cell["smoothness"] == 0.0:
            assert plain / ref < 0.88, plain / ref
            assert abs(corrected / ref - 1) < 0.05, corrected / ref
