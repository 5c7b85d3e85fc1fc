"""The white furnace on the shipped OSL shader: the rendered specular directional albedo
matches brute-force quadrature of the model's formulas (tests/reference_model.py) view angle by
view angle, never exceeds 1, and the two G models differ as the quadrature says."""

import numpy as np
import pytest

from addon.jobs import pipeline

from addon.core import energy
from addon.core.compare import read_image
from reference_model import specular_albedo

# The white furnace: the same on every Blender series, so run on one
# (docs/testing.md, "Which tests run on both series").
pytestmark = pytest.mark.one_series


def _expected_image(scene, g_model):
    """Per pixel, the quadrature's E(n.v) (interpolated on a grid of n.v) at that pixel's n.v."""
    img = np.zeros((scene["height"], scene["width"], 3), dtype=np.float32)
    yy, xx = np.mgrid[0 : scene["height"], 0 : scene["width"]] + 0.5
    mus = np.linspace(0.02, 1.0, 25)
    for cell in scene["cells"]:
        if cell["smoothness"] > 0.7:  # lobes narrower than the quadrature grid resolves
            continue
        table = [
            float(
                specular_albedo(
                    mu,
                    (1.0, 1.0, 1.0),
                    1.0,
                    cell["smoothness"],
                    g_model=g_model,
                    n_theta=300,
                    n_phi=240,
                )[0]
            )
            for mu in mus
        ]
        cx, cy = cell["center_px"]
        d = np.hypot(xx - cx, yy - cy) / cell["radius_px"]
        inside = d < 1
        img[inside] = np.interp(np.sqrt(1 - d[inside] ** 2), mus, table)[:, None]
    return img


@pytest.fixture(scope="module")
def furnace(tmp_path_factory):
    out = tmp_path_factory.mktemp("furnace")
    curves, expected = {}, {}
    for g in ("cook_torrance", "smith_ggx_correlated"):
        scene = pipeline.render_one(energy.furnace_settings(g), out / g, 16)
        curves[g] = energy.directional_albedo(read_image(out / g / "render.exr"), scene)
        expected[g] = energy.directional_albedo(_expected_image(scene, g), scene)
    return curves, expected


def test_furnace_albedo_matches_quadrature_and_never_exceeds_one(furnace):
    curves, expected = furnace
    for g in curves:
        for got, want in zip(curves[g], expected[g]):
            for theta, e, x, n in zip(
                got["theta_deg"], got["albedo"], want["albedo"], got["pixels"]
            ):
                if e is None:  # no pixel at that view angle
                    continue
                assert e <= 1.0 + 0.01, (g, got["smoothness"], theta, e)
                if n >= 40 and theta < 80 and got["smoothness"] < 0.7:
                    assert abs(e - x) < 0.025, (g, got["smoothness"], theta, e, x)


def test_cook_torrance_g_keeps_more_energy_than_smith_when_rough(furnace):
    """Quadrature of the model's formulas: at high roughness the V-cavity (Cook-Torrance) G masks
    less than Smith's, so it keeps more energy, most at grazing views; smooth, they agree."""
    curves, _ = furnace
    ct, smith = (curves[g] for g in ("cook_torrance", "smith_ggx_correlated"))
    by_s = {round(c["smoothness"], 2): i for i, c in enumerate(ct)}
    rough = by_s[0.0]
    assert energy.mean_albedo(ct[rough]) > energy.mean_albedo(smith[rough]) + 0.08
    assert ct[rough]["albedo"][7] > smith[rough]["albedo"][7] + 0.15  # 70-80 degrees
    smooth = by_s[1.0]
    assert abs(energy.mean_albedo(ct[smooth]) - energy.mean_albedo(smith[smooth])) < 0.01
    # and single scattering loses energy with roughness, monotonically
    means = [energy.mean_albedo(c) for c in smith]
    assert means == sorted(means, reverse=True) and means[-1] < 0.5


@pytest.mark.parametrize("ibl", ["reference", "split_sum"])
def test_compensated_energy_fills_the_white_furnace(ibl, tmp_path):
    """With Kulla and Conty's multiple-scattering lobe (--energy compensated), a white metal
    in a white furnace reflects everything: the rendered specular directional albedo lies in
    [0.97, 1.01] at every roughness and resolved view angle, for every G, through the
    reference integration and the split-sum (single scattering loses up to 60%)."""
    from addon.core.model import G_MODELS

    for g in G_MODELS:
        scene = pipeline.render_one(
            energy.furnace_settings(g, energy="compensated", ibl=ibl), tmp_path / g, 16
        )
        curves = energy.directional_albedo(read_image(tmp_path / g / "render.exr"), scene)
        seen = 0
        for curve in curves:
            for theta, e, n in zip(curve["theta_deg"], curve["albedo"], curve["pixels"]):
                if e is None or n < 40 or theta >= 80:
                    continue
                seen += 1
                assert 0.97 <= e <= 1.01, (g, ibl, curve["smoothness"], theta, e)
        assert seen > 20, (g, seen)


def test_compensation_saturates_a_coloured_metal(tmp_path):
    """Kulla and Conty's Fresnel term weights the energy that scatters again by F_avg, once per
    extra bounce: a gold metal in the white furnace gains energy and saturation, most where it
    is rough. On the roughest sphere, per channel, the compensated albedo over the single-
    scattering one is 1 + F_ms (1 - E)/E (E the rendered uncompensated albedo of a white metal,
    F_ms from Schlick's average), within 3%; blue gains less than red."""
    from addon.core.settings import with_overrides

    gold = (1.0, 0.766, 0.336)
    means = {}
    for mode in ("none", "compensated"):
        for albedo in (gold, (1.0, 1.0, 1.0)):
            s = with_overrides(
                energy.furnace_settings("smith_ggx_correlated", energy=mode), {"albedo": albedo}
            )
            folder = tmp_path / f"{mode}-{albedo[2]}"
            scene = pipeline.render_one(s, folder, 16)
            img = read_image(folder / "render.exr")
            cell = max(scene["cells"], key=lambda c: -c["smoothness"])  # the roughest
            cx, cy = cell["center_px"]
            yy, xx = np.mgrid[0 : img.shape[0], 0 : img.shape[1]] + 0.5
            inside = np.hypot(xx - cx, yy - cy) < 0.5 * cell["radius_px"]  # n.v > 0.87
            means[mode, albedo[2]] = img[inside][:, :3].mean(axis=0)
    single, compensated = means["none", gold[2]], means["compensated", gold[2]]
    E = means["none", 1.0].mean()
    e_avg = 0.409  # Smith's E_avg at pr = 1 (ms table)
    f_avg = np.array(gold) + (1 - np.array(gold)) / 21
    f_ms = f_avg * e_avg / (1 - f_avg * (1 - e_avg))
    want = 1 + f_ms * (1 - E) / E
    np.testing.assert_allclose(compensated / single, want, rtol=0.03)
    saturation = [1 - c.min() / c.max() for c in (single, compensated)]
    assert saturation[1] > saturation[0] + 0.02, saturation
    assert (compensated / single)[0] > (compensated / single)[2] + 0.1
