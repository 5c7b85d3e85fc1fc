"""The BRDF plots (``ctlab plot``; addon/core/brdf_plot.py, docs/model.md "BRDF plots"):
values rendered by the model's own code (a pixel per configuration) against closed forms
written from the angles alone, the OSL shader against the node group, the directional albedo
against brute-force quadrature and closed forms, and the files the command writes."""

import json
import math
import xml.etree.ElementTree as ET

import numpy as np
import pytest

from reference_model import specular_albedo
from addon.core import brdf_plot as bp
from addon.core.errors import UserError
from addon.jobs import cli, plot_job

# The BRDF plots' quadratures: the same on every Blender series, so run on one
# (docs/testing.md, "Which tests run on both series").
pytestmark = pytest.mark.one_series

EPS32 = 6e-8  # float32's unit roundoff


# ----------------------------------------------------------------------------------------
# The model from the cosines of one configuration, written from docs/model.md alone


def model_from_cosines(
    nl,
    nv,
    nh,
    vh,
    metallic,
    smoothness,
    albedo,
    g_model="cook_torrance",
    diffuse="disney",
    units="physical",
):
    """(f_s, f_d, D, F, G) in float64, broadcast; l.h = v.h."""
    nl, nv, nh, vh = (np.asarray(x, dtype=np.float64) for x in (nl, nv, nh, vh))
    albedo = np.asarray(albedo, dtype=np.float64)
    pr = 1.0 - smoothness
    a = max(pr * pr, 0.002)
    a2 = a * a
    D = a2 / (np.pi * (nh * nh * (a2 - 1) + 1) ** 2)
    spec = 0.04 * (1 - metallic) + albedo * metallic
    F = spec + (1 - spec) * ((1 - vh) ** 5)[..., None]
    if g_model == "cook_torrance":
        G = np.minimum(1, np.minimum(2 * nh * nv / vh, 2 * nh * nl / vh))
    elif g_model == "smith_ggx_correlated":
        G = (
            2
            * nl
            * nv
            / (nl * np.sqrt(nv * nv * (1 - a2) + a2) + nv * np.sqrt(nl * nl * (1 - a2) + a2))
        )
    else:  # Unity's SmithJointGGXVisibilityTerm, as a G
        G = 4 * nl * nv * 0.5 / (nl * (nv * (1 - a) + a) + nv * (nl * (1 - a) + a) + 1e-5)
    fs = D[..., None] * F * G[..., None] / (4 * nl * nv)[..., None]
    diff = albedo * 0.96 * (1 - metallic)
    if diffuse == "disney":
        fd90 = 0.5 + 2 * vh * vh * pr
        fd = (
            diff
            / np.pi
            * ((1 + (fd90 - 1) * (1 - nl) ** 5) * (1 + (fd90 - 1) * (1 - nv) ** 5))[..., None]
        )
    else:
        fd = diff / np.pi * np.ones_like(nl)[..., None]
    k = np.pi if units == "unity" else 1.0
    return k * fs, k * fd, D, F, G


def slice_cosines():
    """At phi_d = 90 degrees: n.h = cos th, l.h = v.h = cos td, n.l = n.v = cos th cos td."""
    th, td = bp.slice_angles()
    TD, TH = np.meshgrid(np.radians(td), np.radians(th), indexing="ij")
    c = np.cos(TH) * np.cos(TD)
    return c, c, np.cos(TH), np.cos(TD)


def lobe_cosines():
    """In the incidence plane: n.l = cos tl, n.v = cos tv, n.h = cos((tl + tv)/2), v.h =
    cos((tv - tl)/2)."""
    tv = np.radians(np.array(bp.LOBE_VIEW_ANGLES))[:, None]
    tl = np.radians(bp.lobe_angles())[None, :]
    tv, tl = np.broadcast_arrays(tv, tl)
    return np.cos(tl), np.cos(tv), np.cos((tl + tv) / 2), np.cos((tv - tl) / 2)


def tolerance(want, nl, nv, nh, vh, alpha, floor=1e-5):
    """Relative 1e-5, widened by the conditioning of the formulas on float32 inputs: an
    absolute error e in each cosine moves f by (1/n.l + 1/n.v + 1/v.h + 5 + cond_D) e,
    cond_D = 4 (n.h)^2 |a^2 - 1| / ((n.h)^2 (a^2 - 1) + 1) (D's denominator cancels near
    the peak; the term-view tests use the same bound). e = 8 EPS32 = 4.8e-7: Blender 4.5's
    OSL computes the cosines to about 16 EPS32 (its G at td = 88.5 deg, where v.h = 0.026,
    was 7e-5 off, the node group's and 5.2's OSL 1e-5), within the 2 e a ratio of two of
    them allows."""
    a2 = alpha * alpha
    cond_d = 4 * nh**2 * abs(a2 - 1) / (nh**2 * (a2 - 1) + 1)
    with np.errstate(divide="ignore"):
        k = 1 / nl + 1 / nv + 1 / vh + 5 + cond_d
    rel = floor + 8 * EPS32 * k
    return rel[..., None] * np.abs(want) + 1e-12


# ----------------------------------------------------------------------------------------
# The fast tier: geometry, quadrature, settings
def test_rusinkiewicz_configurations_have_the_half_and_difference_angles():
    """h = normalize(l + v) is (sin th, 0, cos th) and l.h = cos td: swapping th and td, or
    the rows and the columns of the slice, fails."""
    rng = np.random.default_rng(1)
    th, td, pd = (
        rng.uniform(0, np.pi / 2, 50),
        rng.uniform(0, np.pi / 2, 50),
        rng.uniform(0, 2 * np.pi, 50),
    )
    l, v = bp.rusinkiewicz(th, td, pd)
    np.testing.assert_allclose(np.linalg.norm(l, axis=-1), 1, atol=1e-12)
    h = (l + v) / np.linalg.norm(l + v, axis=-1, keepdims=True)
    np.testing.assert_allclose(h, np.stack([np.sin(th), 0 * th, np.cos(th)], -1), atol=1e-12)
    np.testing.assert_allclose(np.sum(l * h, -1), np.cos(td), atol=1e-12)
    l, v = bp.slice_geometry()
    assert l.shape == (90, 90, 3)
    nl, nv, nh, vh = slice_cosines()
    np.testing.assert_allclose(l[..., 2], nl, atol=1e-12)  # row j: td_j, column i: th_i
    np.testing.assert_allclose(v[..., 2], nv, atol=1e-12)
    assert l[0, 89, 0] > 0.99 and l[89, 0, 1] > 0.99  # th = 89.5 at the right, td below


def test_the_view_frame_puts_v_on_z_and_keeps_every_angle():
    rng = np.random.default_rng(2)
    v = rng.normal(size=(200, 3))
    v[:, 2] = np.abs(v[:, 2]) + 0.05
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    l = rng.normal(size=(200, 3))
    l /= np.linalg.norm(l, axis=1, keepdims=True)
    n1, l1 = bp.view_frame(v, l)
    z = np.array([0.0, 0.0, 1.0])
    np.testing.assert_allclose(np.linalg.norm(n1, axis=1), 1, atol=1e-12)
    np.testing.assert_allclose(n1 @ z, v[:, 2], atol=1e-12)  # n'.v' = n.v
    np.testing.assert_allclose(l1 @ z, np.sum(l * v, 1), atol=1e-12)  # l'.v' = l.v
    np.testing.assert_allclose(np.sum(n1 * l1, 1), l[:, 2], atol=1e-12)  # n'.l' = n.l


def _quadrature_albedo(smooth, tv, g_model="cook_torrance", metallic=1.0):
    """The plot's specular quadrature applied to the closed forms: (n.l) f_s weight / D."""
    a = max((1 - smooth) ** 2, 0.002)
    l, v, w = bp.specular_quadrature(np.array([tv]), a)
    h = (l[0] + v[0]) / np.linalg.norm(l[0] + v[0], axis=-1, keepdims=True)
    nl = l[0, :, 2]
    fs, _, D, _, _ = model_from_cosines(
        np.maximum(nl, 1e-12),
        v[0, 0, 2],
        h[:, 2],
        np.sum(v[0] * h, -1),
        metallic,
        smooth,
        (0.8, 0.8, 0.8),
        g_model,
    )
    return float(np.sum(np.where(nl > 0, fs[:, 0] * nl * w[0] / D, 0.0)))


def test_the_quadratures_integrate_known_integrals():
    """The cosine over the hemisphere is pi (the specular quadrature at alpha 1, where D =
    1/pi and every direction is reached); a Lambertian f = 1/pi has albedo 1; the specular
    albedo of each G agrees with brute-force quadrature over (theta, phi) (n_theta 1200, n_phi
    400, which converges there: within 1.1e-6 of n_theta 4000; n_phi 200 moves it 2e-4) at
    smoothness 0, 0.3 and 0.5 from 1 to 83 degrees within 1e-3 (measured 6e-4 at most),
    and a mirror's is Schlick's F of n.v (G = 1 at the mirror direction)."""
    tv = np.array([0.5, 30.0, 60.0])
    l, v, w = bp.specular_quadrature(tv, 1.0)
    np.testing.assert_allclose(np.sum(np.maximum(l[..., 2], 0) * w * np.pi, 1), np.pi, rtol=2e-3)
    l, v, w = bp.diffuse_quadrature(tv)
    np.testing.assert_allclose(np.sum(l[..., 2] * w / np.pi, 1), 1.0, rtol=1e-9)
    for g_model in ("cook_torrance", "smith_ggx_correlated", "unity_smith_joint"):
        for smooth in (0.0, 0.3, 0.5):
            for t in (1.0, 45.0, 83.0):
                got = _quadrature_albedo(smooth, t, g_model)
                want = specular_albedo(
                    math.cos(math.radians(t)),
                    np.array([0.8] * 3),
                    1.0,
                    smooth,
                    g_model=g_model,
                    n_theta=1200,
                    n_phi=400,
                )[0]
                assert abs(got - want) < 1e-3 * want, (g_model, smooth, t, got, want)
    got = _quadrature_albedo(1.0, 30.0)
    assert abs(got - (0.8 + 0.2 * (1 - math.cos(math.radians(30))) ** 5)) < 2e-3


def test_the_layout_packs_and_unpacks_every_configuration():
    s = bp.PlotSettings(metallic=1.0, smoothness=0.5)
    lay = bp.layout(s)
    w, h = lay.size
    assert lay.n.shape == (h, w, 3) and w * h >= lay.count > w * (h - 1)
    image = np.zeros((h, w, 3), dtype=np.float32)
    image.reshape(-1, 3)[:, 0] = np.arange(w * h)
    parts = lay.unpack(image)
    assert parts["slice"].shape == (90, 90, 3) and parts["slice"][0, 1, 0] == 1
    assert parts["lobe"][0, 0, 0] == 90 * 90
    np.testing.assert_allclose(np.linalg.norm(lay.n, axis=-1), 1, atol=1e-12)


@pytest.mark.parametrize(
    "kw, words",
    [
        (dict(metallic=1.5), "metallic 1.5 out of range"),
        (dict(smoothness=-0.1), "smoothness -0.1 out of range"),
        (dict(smoothness=float("nan")), "smoothness nan out of range"),
        (dict(albedo=(1, 1)), "malformed albedo"),
        (dict(albedo=(1, 2, 0.5)), "albedo 2.0 out of range"),
        (dict(g_model="beckmann"), "unknown G"),
        (dict(shader="principled"), "unknown shader 'principled' for a plot"),
        (dict(views=("full",)), "cannot be sliced"),
    ],
)
def test_bad_plot_settings_are_refused_in_one_line(kw, words):
    with pytest.raises(UserError) as e:
        bp.PlotSettings(**kw)
    assert words in str(e.value) and "\n" not in str(e.value)


def test_compare_items_are_parsed_and_checked():
    assert bp.parse_compare(
        [
            "g=smith_ggx_correlated,g=unity_smith_joint",
            "energy=compensated",
            "g=smith_ggx_correlated",
        ]
    ) == (("g", "smith_ggx_correlated"), ("g", "unity_smith_joint"), ("energy", "compensated"))
    for bad in ("g", "x=1", "g=beckmann", "=lambert"):
        with pytest.raises(UserError):
            bp.parse_compare([bad])
    s = bp.PlotSettings(compare=bp.parse_compare(["g=cook_torrance,diffuse=lambert"]))
    assert [t for t, _, _ in s.variants()] == ["", "diffuse-lambert"]  # no-op variant dropped


# ----------------------------------------------------------------------------------------
# Rendered: the model's own code

CASES = {
    "seed_metal": dict(metallic=1.0, smoothness=0.5, albedo=(1.0, 0.766, 0.336)),
    "smith_lambert_dielectric": dict(
        metallic=0.0, smoothness=0.9, g_model="smith_ggx_correlated", diffuse_model="lambert"
    ),
    "unity_rough_unity_units": dict(
        metallic=0.3,
        smoothness=0.1,
        g_model="unity_smith_joint",
        units="unity",
        albedo=(0.2, 0.5, 0.9),
    ),
    "mirror": dict(metallic=1.0, smoothness=1.0),
}


@pytest.fixture(scope="module", params=list(CASES))
def evaluated(request):
    s = bp.PlotSettings(views=("D", "F", "G"), **CASES[request.param])
    out = {
        shader: plot_job.evaluate_plot(
            bp.PlotSettings(shader=shader, views=s.views, **CASES[request.param])
        )
        for shader in ("osl", "nodes")
    }
    return s, out


def _want(s, cosines):
    return model_from_cosines(
        *cosines, s.metallic, s.smoothness, s.albedo, s.g_model, s.diffuse_model, s.units
    )


@pytest.mark.parametrize("shader", ["osl", "nodes"])
def test_the_slice_is_the_model_at_each_half_and_difference_angle(evaluated, shader):
    """slice.exr pixel (i, j) is f_d + f_s at th = i + 0.5, td = j + 0.5 degrees (phi_d 90),
    from closed forms in the angles alone, and the D, F and G slices likewise. Caught: rows
    and columns swapped (100% off), the slice's rows flipped, l and v exchanged in the
    Disney term (no: symmetric) or F on n.v instead of v.h (4% at td 60)."""
    s, out = evaluated
    cos = slice_cosines()
    fs, fd, D, F, G = _want(s, cos)
    got = out[shader][""]["slice"]
    for name, want in (("f_r", fs + fd), ("D", D[..., None]), ("F", F), ("G", G[..., None])):
        want = np.broadcast_to(want, got[name].shape)
        bad = np.abs(got[name] - want) > tolerance(want, *cos, s.alpha)
        assert not bad.any(), (name, int(bad.sum()), got[name][bad][:3], want[bad][:3])


def test_the_osl_shader_and_the_node_group_give_the_same_slice(evaluated):
    """1e-5 relative, widened only by the formulas' conditioning on float32 inputs: each
    implementation within ``tolerance`` of the model, so the two within twice that (the
    worst pixel, on 4.5 at td 88.5 deg, needed 1.02 times the single allowance)."""
    s, out = evaluated
    cos = slice_cosines()
    a, b = out["osl"][""]["slice"]["f_r"], out["nodes"][""]["slice"]["f_r"]
    assert not (np.abs(a - b) > 2 * tolerance(a, *cos, s.alpha)).any()
    la, lb = out["osl"][""]["lobe"], out["nodes"][""]["lobe"]
    nl, nv, nh, vh = lobe_cosines()
    ok = nl > 1e-3
    assert (np.abs(la - lb) <= 2 * tolerance(la, nl, nv, nh, vh, s.alpha))[ok].all()


def test_osl_and_nodes_agree_with_energy_compensated():
    """With energy compensated both read E(n.v) from the ms table (OSL's texture() against an
    Environment Texture node): 3e-4, as tests/render/test_node_group.py allows the same lookup."""
    kw = dict(
        metallic=0.5,
        smoothness=0.3,
        g_model="smith_ggx_correlated",
        energy="compensated",
        albedo=(0.9, 0.6, 0.3),
    )
    a, b = (plot_job.evaluate_plot(bp.PlotSettings(shader=sh, **kw))[""] for sh in ("osl", "nodes"))
    cos = slice_cosines()
    alpha = bp.PlotSettings(**kw).alpha
    assert not (
        np.abs(a["slice"]["f_r"] - b["slice"]["f_r"])
        > 2 * tolerance(a["slice"]["f_r"], *cos, alpha, floor=1.5e-4)
    ).any()
    np.testing.assert_allclose(a["albedo"]["total"], b["albedo"]["total"], rtol=3e-4)
    uncompensated = plot_job.evaluate_plot(bp.PlotSettings(**dict(kw, energy="none")))[""]
    gain = a["albedo"]["specular"] / uncompensated["albedo"]["specular"]
    # the compensation is there (in both; measured 1.18 at normal incidence, 1.006 at 89
    # degrees in blue)
    assert gain.min() > 1.002 and gain[0].max() > 1.1, (gain.min(), gain[0])


def test_the_lobes_are_the_model_in_the_incidence_plane(evaluated):
    """lobe = f_r (n.l) at (tv, tl) from closed forms; its peak sits at the mirror
    direction tl = -tv for a smooth metal."""
    s, out = evaluated
    nl, nv, nh, vh = lobe_cosines()
    fs, fd, *_ = _want(s, (np.maximum(nl, 1e-12), nv, nh, vh))
    want = (fs + fd) * np.maximum(nl, 0)[..., None]
    got = out["osl"][""]["lobe"]
    ok = nl > 1e-3
    bad = (np.abs(got - want) > tolerance(want, nl, nv, nh, vh, s.alpha))[ok]
    assert not bad.any(), int(bad.sum())
    if s.metallic == 1 and s.smoothness >= 0.5:
        for i, tv in enumerate(bp.LOBE_VIEW_ANGLES):
            peak = bp.lobe_angles()[np.argmax(got[i, :, 0])]
            assert abs(peak + tv) <= 0.5, (tv, peak)


def test_the_directional_albedo_against_independent_quadrature(evaluated):
    """The albedo from the rendered f_s and f_d equals the same quadratures of the closed
    forms (1e-4; every case, Unity's G and units included: a wrong weight, unit or packing
    fails), Lambert's is diffColor exactly, the specular part agrees with brute-force
    quadrature over (theta, phi) (n_theta 3000) within 2e-3 from 1 to 75 degrees where that
    converges (pr >= 0.5), and a mirror's is Schlick's F of n.v."""
    s, out = evaluated
    alb = out["osl"][""]["albedo"]
    tv = bp.albedo_angles()
    k_units = np.pi if s.units == "unity" else 1.0
    l, v, w = bp.specular_quadrature(tv, s.alpha)
    h = (l + v) / np.linalg.norm(l + v, axis=-1, keepdims=True)
    nl = l[..., 2]
    fs, _, D, _, _ = _want(s, (np.maximum(nl, 1e-12), v[..., 2], h[..., 2], np.sum(v * h, -1)))
    want = np.sum(np.where((nl > 0)[..., None], fs * (nl * w / D)[..., None], 0), axis=1)
    np.testing.assert_allclose(alb["specular"], want, rtol=1e-4)
    l, v, w = bp.diffuse_quadrature(tv)
    h = (l + v) / np.linalg.norm(l + v, axis=-1, keepdims=True)
    _, fd, *_ = _want(s, (l[..., 2], v[..., 2], h[..., 2], np.sum(v * h, -1)))
    np.testing.assert_allclose(
        alb["diffuse"], np.sum(fd * (l[..., 2] * w)[..., None], axis=1), rtol=1e-4, atol=1e-9
    )
    if s.diffuse_model == "lambert":
        want = np.array(s.albedo) * 0.96 * (1 - s.metallic) * k_units
        np.testing.assert_allclose(
            alb["diffuse"], np.broadcast_to(want, alb["diffuse"].shape), rtol=1e-5, atol=1e-7
        )
    if s.smoothness <= 0.5 and s.g_model != "unity_smith_joint":
        for k in (0, 22, 37):
            want = (
                specular_albedo(
                    math.cos(math.radians(tv[k])),
                    np.array(s.albedo),
                    s.metallic,
                    s.smoothness,
                    g_model=s.g_model,
                    n_theta=3000,
                    n_phi=600,
                )
                * k_units
            )
            np.testing.assert_allclose(alb["specular"][k], want, rtol=2e-3)
    if s.smoothness == 1.0:
        mu = np.cos(np.radians(tv[:40]))
        spec = np.array(s.albedo)
        want = spec + (1 - spec) * ((1 - mu) ** 5)[:, None]
        np.testing.assert_allclose(alb["specular"][:40], want, rtol=3e-3)
    np.testing.assert_allclose(alb["total"], alb["specular"] + alb["diffuse"], rtol=1e-12)


def test_compensated_energy_fills_the_white_furnace_in_the_plot():
    """With energy compensated a white metal's plotted directional albedo is 1 (the furnace
    bound of tests/slow/test_energy.py, [0.97, 1.01]) at every view angle below 85 degrees, and
    the uncompensated one loses energy (below 0.9 somewhere) at smoothness 0."""
    s = bp.PlotSettings(
        metallic=1.0, smoothness=0.0, albedo=(1, 1, 1), compare=(("energy", "compensated"),)
    )
    out = plot_job.evaluate_plot(s)
    tv = bp.albedo_angles()
    comp = out["energy-compensated"]["albedo"]["specular"][tv < 85, 0]
    assert comp.min() >= 0.97 and comp.max() <= 1.01, (comp.min(), comp.max())
    assert out[""]["albedo"]["specular"][:, 0].min() < 0.9


# ----------------------------------------------------------------------------------------
# The command


def test_ctlab_plot_writes_every_file(tmp_path):
    out = tmp_path / "plot"
    code = cli.main(
        [
            "plot",
            "--metallic",
            "1",
            "--smoothness",
            "0.6",
            "--albedo",
            "1,0.766,0.336",
            "--view",
            "D,F",
            "--view",
            "G",
            "--compare",
            "g=smith_ggx_correlated,g=unity_smith_joint",
            "--out",
            str(out),
        ]
    )
    assert code == 0
    data = json.loads((out / "plot.json").read_text())
    for name in data["files"]:
        assert (out / name).is_file(), name
    names = set(data["files"])
    for name in (
        "slice.exr",
        "slice.png",
        "slice_D.exr",
        "slice_F.png",
        "slice_G.exr",
        "slice_g-smith_ggx_correlated.exr",
        "slice_g-unity_smith_joint.png",
        "lobe.svg",
        "lobe.png",
        "albedo.csv",
        "albedo.svg",
        "plot.png",
        "plot.json",
    ):
        assert name in names, name
    from addon.core.compare import read_image

    img = read_image(out / "slice.exr")
    assert img.shape == (90, 90, 3) and np.isfinite(img).all() and img.min() >= 0
    assert data["slice"]["theta_h_deg"][0] == 0.5 and data["slice"]["phi_d_deg"] == 90
    assert [v["tag"] for v in data["variants"]] == [
        "",
        "g-smith_ggx_correlated",
        "g-unity_smith_joint",
    ]
    ET.fromstring((out / "lobe.svg").read_text())  # well-formed
    ET.fromstring((out / "albedo.svg").read_text())
    rows = (out / "albedo.csv").read_text().splitlines()
    assert len(rows) == 1 + bp.ALBEDO_ANGLES and rows[0].startswith("theta_v_deg,specular_r")
    values = np.array([[float(x) for x in r.split(",")] for r in rows[1:]])
    assert (
        np.isfinite(values).all() and values.shape[1] == 1 + 3 * 9
    )  # 3 variants x (specular, diffuse, total) x RGB
    assert not list(out.glob(".*partial*"))


# ----------------------------------------------------------------------------------------
# The plots' cache (jobs/plot_cache.py)


def _same_results(a, b, where=""):
    """The same nested keys in the same order, arrays equal exactly with their dtypes."""
    assert list(a) == list(b), where
    for k in a:
        if isinstance(a[k], dict):
            _same_results(a[k], b[k], f"{where}/{k}")
        elif isinstance(a[k], str):
            assert a[k] == b[k], (where, k)
        else:
            x, y = np.asarray(a[k]), np.asarray(b[k])
            assert x.dtype == y.dtype and x.shape == y.shape, (where, k)
            assert np.array_equal(x, y), (where, k)


def test_a_plot_is_rendered_once_then_read_from_the_cache(tmp_path, monkeypatch):
    """The second evaluation of the same plot renders nothing and gives the first's results
    exactly (every array, dtype and label); a damaged entry is rendered again, never read;
    the key changes with every setting and with the add-on's sources."""
    from addon.jobs import plot_cache

    monkeypatch.setenv("CTLAB_CACHE", str(tmp_path / "cache"))
    rendered = []
    render = plot_job.render_plot
    monkeypatch.setattr(
        plot_job, "render_plot", lambda *a, **k: rendered.append(a[0]) or render(*a, **k)
    )
    fields = dict(
        metallic=1.0, smoothness=0.3, views=("D",), compare=(("g", "smith_ggx_correlated"),)
    )
    s = bp.PlotSettings(**fields)
    first = plot_job.evaluate_plot(s)
    assert len(rendered) == 1 and list(first) == ["", "g-smith_ggx_correlated", "labels"]
    second = plot_job.evaluate_plot(s)
    assert len(rendered) == 1
    _same_results(first, second)
    entry = tmp_path / "cache" / plot_cache.key(s) / plot_cache.RESULTS
    entry.write_bytes(entry.read_bytes()[:-100])  # truncated: the manifest catches it
    third = plot_job.evaluate_plot(s)
    assert len(rendered) == 2
    _same_results(first, third)
    keys = {plot_cache.key(s)}
    for change in (
        dict(metallic=0.9),
        dict(smoothness=0.31),
        dict(albedo=(0.9, 0.9, 0.8)),
        dict(g_model="unity_smith_joint"),
        dict(diffuse_model="lambert"),
        dict(units="unity"),
        dict(energy="compensated"),
        dict(shader="nodes"),
        dict(views=("D", "F")),
        dict(compare=()),
    ):
        keys.add(plot_cache.key(bp.PlotSettings(**dict(fields, **change))))
    assert len(keys) == 11
    monkeypatch.setattr(plot_cache, "_sources_digest", lambda: "another shader")
    assert plot_cache.key(s) not in keys
