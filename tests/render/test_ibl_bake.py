"""The split-sum bake (addon/core/ibl_bake.py, its lat-long convolution
addon/core/latlong.py): the DFG table against brute-force quadrature, pre-filtered levels and
irradiance against closed forms, the cache, and bad input."""

import json
import os
import subprocess
import sys

import numpy as np
import pytest

from helpers import ROOT, bad_images
from reference_model import specular_albedo
from addon.core import ibl_bake, latlong
from addon.core.compare import read_image
from addon.core.errors import UserError
from addon.core.hdri import write_float_exr
from addon.core.model import G_MODELS


CTLAB = [sys.executable, str(ROOT / "scripts" / "ctlab.py")]
N = ibl_bake.DFG_SIZE


def _bake(pixels, path):
    write_float_exr(path, np.asarray(pixels, dtype=np.float32))
    return ibl_bake.bake(path)


def _directions(h, w):
    """Unit direction of each texel centre of a lat-long image (Blender's mapping)."""
    e = latlong.row_elevations(h)[:, None]
    s = (np.arange(w) + 0.5)[None, :] / w
    phi = (0.5 - s) * 2 * np.pi
    return np.stack(
        np.broadcast_arrays(np.cos(e) * np.cos(phi), np.cos(e) * np.sin(phi), np.sin(e)), axis=-1
    )


@pytest.fixture(scope="module")
def forest_bake():
    from addon.blender.paths import bundled_hdri

    return ibl_bake.bake(bundled_hdri("forest"))


# --- DFG ---------------------------------------------------------------------------------

# (row j: pr = j/(N-1), column i: n.v = i/(N-1)), from near-mirror to rough, grazing to normal
DFG_ENTRIES = (
    (12, 40),
    (12, 63),
    (20, 12),
    (32, 3),
    (32, 30),
    (48, 3),
    (48, 50),
    (63, 20),
    (63, 63),
)


@pytest.mark.parametrize("g_model", G_MODELS)
def test_dfg_table_matches_brute_force_quadrature(forest_bake, g_model):
    """A and B read from the baked EXR equal the directional albedo of f_s integrated by
    brute-force midpoint quadrature over (theta_l, phi_l) of the model's formulas (F0 = 1 gives
    A + B, F0 = 0 gives B), to 1e-3; so does the Disney factor (f_d of diffColor 1)."""
    table = read_image(forest_bake / ibl_bake.dfg_file(g_model))
    assert table.shape == (N, N, 3)
    for j, i in DFG_ENTRIES:
        nv, pr = i / (N - 1), j / (N - 1)
        f0_one_and_zero = specular_albedo(
            nv, np.array([1.0, 0.0, 0.0]), 1.0, 1 - pr, g_model=g_model, n_theta=1200, n_phi=600
        )
        a, b, k = table[j, i]
        assert abs(a + b - f0_one_and_zero[0]) < 1e-3, (j, i, a + b, f0_one_and_zero[0])
        assert abs(b - f0_one_and_zero[1]) < 1e-3, (j, i, b, f0_one_and_zero[1])
    for j, i in ((0, 3), (32, 30), (63, 60), (63, 3), (63, 63)):
        nv, pr = i / (N - 1), j / (N - 1)
        disney = specular_albedo(nv, np.full(3, 1 / 0.96), 0.0, 1 - pr, term="diffuse_brdf")[0]
        assert abs(table[j, i, 2] - disney) < 1e-3, (j, i, table[j, i, 2], disney)


def test_smith_directional_albedo_tends_to_one_as_roughness_vanishes(forest_bake):
    """F = 1, alpha -> 0: the height-correlated Smith G -> 1, so A + B -> 1 (first row,
    alpha = 0.002), away from the most grazing columns; roughness loses energy."""
    table = read_image(forest_bake / ibl_bake.dfg_file("smith_ggx_correlated"))
    albedo = table[:, :, 0] + table[:, :, 1]
    nv = np.arange(N) / (N - 1)
    assert np.all(np.abs(albedo[0, nv >= 0.1] - 1) < 1e-3), albedo[0]
    assert np.all(albedo[0] <= 1 + 1e-4)
    assert albedo[0, 32] > albedo[32, 32] > albedo[63, 32]


# --- Levels and irradiance ---------------------------------------------------------------


def test_uniform_world_bakes_to_ones_and_pi(tmp_path):
    folder = _bake(np.ones((64, 128, 3)), tmp_path / "white.exr")
    info = json.loads((folder / ibl_bake.INFO_FILE).read_text())
    assert [lv["perceptual_roughness"] for lv in info["levels"]] == pytest.approx(
        [m / 6 for m in range(7)]
    )
    for m in range(ibl_bake.LEVEL_COUNT):
        level = read_image(folder / ibl_bake.level_file(m))
        np.testing.assert_allclose(level, 1.0, atol=1e-5, err_msg=f"level {m}")
    irr = read_image(folder / ibl_bake.IRRADIANCE_FILE)
    np.testing.assert_allclose(irr, np.pi, rtol=1e-5)


def test_irradiance_of_a_bright_upper_hemisphere_is_the_closed_form(tmp_path):
    """Radiance 1 above the horizon, 0 below: E(n) = pi (1 + sin(elevation of n)) / 2."""
    h = 64
    sky = np.zeros((h, 2 * h, 3))
    sky[: h // 2] = 1.0
    folder = _bake(sky, tmp_path / "sky.exr")
    irr = read_image(folder / ibl_bake.IRRADIANCE_FILE)
    e = latlong.row_elevations(irr.shape[0])
    want = np.pi * (1 + np.sin(e)) / 2
    np.testing.assert_allclose(
        irr[:, :, 1], np.broadcast_to(want[:, None], irr.shape[:2]), atol=0.01 * np.pi
    )


def test_a_bright_texel_spreads_into_a_ggx_lobe_that_widens_with_roughness(tmp_path):
    """A 128x64 source: every level is filtered on the source's own grid (no downsampling)."""
    h, w = 64, 128
    src = np.zeros((h, w, 3))
    row, col, power = h // 2 - 1, 100, 1000.0
    src[row, col] = power
    folder = _bake(src, tmp_path / "texel.exr")
    l0 = _directions(h, w)[row, col]
    phi_total = power * latlong.row_solid_angles(h, w)[row]
    widths = []
    for m in range(1, ibl_bake.LEVEL_COUNT):
        level = read_image(folder / ibl_bake.level_file(m))[:, :, 0].astype(np.float64)
        lh, lw = level.shape
        d = _directions(lh, lw)
        dw = latlong.row_solid_angles(lh, lw)[:, None]
        mu = np.clip(d @ l0, -1, 1)
        # the peak is where the texel is; the normalised convolution keeps its power
        peak = np.unravel_index(level.argmax(), level.shape)
        assert np.degrees(np.arccos(mu[peak])) < 1.5 * 180 / lh, (m, peak)
        assert np.sum(level * dw) == pytest.approx(phi_total, rel=0.02), m
        widths.append(np.sqrt(np.sum(level * dw * np.arccos(mu) ** 2) / np.sum(level * dw)))
        if m == 3:
            # its shape is the model's D(h) max(r.l, 0), h = normalize(r + l), carrying the
            # texel's power: P(r) = power K(r.l0) / integral K, the integral by quadrature in mu
            a2 = (0.5**2) ** 2

            def K(c, a2=a2):
                return a2 / (np.pi * ((1 + c) / 2 * (a2 - 1) + 1) ** 2) * np.maximum(c, 0)

            grid = (np.arange(200000) + 0.5) / 200000
            total = 2 * np.pi * np.mean(K(grid))
            near = mu > 0.5
            np.testing.assert_allclose(level[near], phi_total * K(mu[near]) / total, rtol=1e-3)
    assert all(b > a * 1.05 for a, b in zip(widths, widths[1:])), widths  # rms angle (rad)


# --- Cache, atomicity, bad input ---------------------------------------------------------


def test_second_bake_is_a_cache_hit_and_rewrites_nothing(tmp_path, forest_bake):
    messages = []
    from addon.blender.paths import bundled_hdri

    before = {p.name: p.stat().st_mtime_ns for p in forest_bake.iterdir()}
    again = ibl_bake.bake(bundled_hdri("forest"), lambda f, m: messages.append(m))
    assert again == forest_bake
    assert {p.name: p.stat().st_mtime_ns for p in again.iterdir()} == before
    assert messages and messages[-1].startswith("cached")


def test_a_failed_bake_leaves_nothing_in_the_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("CTLAB_CACHE", str(tmp_path / "cache"))  # its own: no other test's bake
    path = tmp_path / "noise.exr"
    write_float_exr(path, np.random.default_rng(7).random((32, 64, 3)).astype(np.float32))
    calls = []

    def failing_write(p, pixels):
        calls.append(p)
        if len(calls) == 3:
            raise UserError("disk full (simulated)")
        write_float_exr(p, pixels)

    monkeypatch.setattr(ibl_bake, "write_float_exr", failing_write)
    with pytest.raises(UserError, match="simulated"):
        ibl_bake.bake(path)
    cache = ibl_bake.cache.cache_dir()
    from addon.core.hdri import file_hash

    leftovers = [
        p.name for p in cache.iterdir() if file_hash(path) in p.name or "partial" in p.name
    ]
    assert leftovers == []


def _run_bake(hdri, out, cache):
    env = dict(os.environ, CTLAB_CACHE=str(cache))
    return subprocess.run(
        CTLAB + ["bake", str(hdri), "--out", str(out)],
        capture_output=True,
        text=True,
        env=env,
        timeout=300,
    )


def test_bake_rejects_bad_images_with_a_clear_message_and_writes_nothing(tmp_path):
    cache = tmp_path / "cache"
    for expected, path in bad_images(tmp_path).items():
        out = tmp_path / f"out-{path.stem}"
        p = _run_bake(path, out, cache)
        assert p.returncode == 2, (expected, p.stdout, p.stderr)
        lines = [ln for ln in p.stderr.splitlines() if ln.startswith("ctlab: error:")]
        assert len(lines) == 1 and expected in lines[0] and str(path) in lines[0], p.stderr
        assert "Traceback" not in p.stderr
        assert not any(out.iterdir()) if out.exists() else True
        assert not cache.exists() or not any(
            p.name.startswith(("ibl-", ".ibl-")) for p in cache.iterdir()
        )


def test_bake_refuses_nan_and_inf_texels_as_the_render_does(tmp_path):
    """One rule for every job (docs/bad-input.md, hdri-nan): an HDRI with NaN/Inf texels is
    refused with the count, before anything is baked or written (the render, which reads the
    same file, would carry them)."""
    px = np.ones((32, 64, 3), dtype=np.float32)
    px[3, 5, 0] = np.nan
    px[10, 20] = np.inf
    px[11, 20, 2] = -np.inf
    path = tmp_path / "nan.exr"
    write_float_exr(path, px)
    out = tmp_path / "out"
    p = _run_bake(path, out, os.environ["CTLAB_CACHE"])
    assert p.returncode == 2, p.stderr
    lines = [line for line in p.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and "3 NaN/Inf pixel(s)" in lines[0], p.stderr
    assert not out.exists() or not any(out.iterdir())


def test_the_cache_misses_on_new_content_at_the_same_path_and_on_new_parameters(
    tmp_path, monkeypatch
):
    """The key is the file's content and the bake's parameters, never its path: rewriting
    the same file, or changing a level's width, bakes anew (and the new level 0 is the new
    content), while an unchanged file and parameters find the first bake."""
    path = tmp_path / "sky.exr"
    write_float_exr(path, np.full((32, 64, 3), 0.25, np.float32))
    first = ibl_bake.bake(path)
    assert ibl_bake.bake(path) == first
    write_float_exr(path, np.full((32, 64, 3), 0.75, np.float32))
    second = ibl_bake.bake(path)
    assert second != first
    np.testing.assert_allclose(read_image(second / ibl_bake.level_file(0)), 0.75)
    monkeypatch.setattr(ibl_bake, "LEVEL_WIDTHS", (0, 256, 256, 128, 64, 64, 64))
    third = ibl_bake.bake(path)
    assert third not in (first, second)


@pytest.mark.parametrize("width", [1024, 1000])
def test_every_level_of_a_real_size_source_against_a_direct_convolution(tmp_path, width):
    """A 1024 x 512 source (whole texel blocks when downsampled) and a 1000 x 500 one (which
    the bake resamples by area): at 40 texel centres of every level k = 1 .. 6, the level is the
    normalised convolution of the source's own texels with D(h) max(r.l, 0) at alpha = (k/6)^2,
    summed directly over all source texels here. The bake convolves the downsampled source
    exactly; what remains is the downsampling: measured at most 0.07% at the median and 0.73% at
    worst (level 1, beside the patch), against bounds of 0.2% and 1.5%."""
    h = width // 2
    rng = np.random.default_rng(width)
    yy, xx = np.mgrid[0:h, 0:width]
    src = (
        0.5
        + 0.3 * np.sin(xx / width * 6 * np.pi)[..., None] * np.cos(yy / h * 3 * np.pi)[..., None]
        + 0.05 * rng.random((h, width, 3))
    ).astype(np.float32)
    src[h // 4 : h // 4 + 12, width // 3 : width // 3 + 20] = 25.0  # a bright patch
    path = tmp_path / f"sky{width}.exr"
    write_float_exr(path, src)
    folder = ibl_bake.bake(path)
    elev = np.pi / 2 - (np.arange(h) + 0.5) * np.pi / h
    phi = (0.5 - (np.arange(width) + 0.5) / width) * 2 * np.pi
    E, P = np.meshgrid(elev, phi, indexing="ij")
    d = np.stack([np.cos(E) * np.cos(P), np.cos(E) * np.sin(P), np.sin(E)], -1).reshape(-1, 3)
    edges = np.pi / 2 - np.arange(h + 1) * np.pi / h
    dw = np.repeat((2 * np.pi / width) * (np.sin(edges[:-1]) - np.sin(edges[1:])), width)
    L = src.reshape(-1, 3).astype(np.float64)
    for k in range(1, ibl_bake.LEVEL_COUNT):
        level = read_image(folder / ibl_bake.level_file(k))
        lh, lw = level.shape[:2]
        rows, cols = rng.integers(0, lh, 40), rng.integers(0, lw, 40)
        # half the points on the patch's neighbourhood, where the lobe's shape matters most
        rows[:20] = rng.integers(int(lh * 0.2), int(lh * 0.32), 20)
        cols[:20] = rng.integers(int(lw * 0.3), int(lw * 0.38), 20)
        e = np.pi / 2 - (rows + 0.5) * np.pi / lh
        ph = (0.5 - (cols + 0.5) / lw) * 2 * np.pi
        r = np.stack([np.cos(e) * np.cos(ph), np.cos(e) * np.sin(ph), np.sin(e)], -1)
        a2 = max((k / 6) ** 2, 0.002) ** 2
        mu = r @ d.T
        kern = a2 / (np.pi * ((1 + mu) / 2 * (a2 - 1) + 1) ** 2) * np.maximum(mu, 0) * dw
        want = (kern @ L) / kern.sum(axis=1, keepdims=True)
        rel = np.abs(level[rows, cols] - want) / want
        assert np.median(rel) < 0.002 and rel.max() < 0.015, (width, k, np.median(rel), rel.max())


@pytest.mark.one_series  # numpy's integration, the same on every Blender series
def test_the_shipped_tables_are_what_integrating_them_gives(tmp_path, monkeypatch):
    """The extension ships the model's tables, DFG and dominant direction (addon/data,
    scripts/build_tables.py) so that a first bake, or the first OSL material, need not
    integrate them (12 s for the dominant directions alone); they must equal a fresh
    integration with today's model and parameters (run the script after changing either),
    and a bake in an empty cache must use them without integrating. Each row (one
    roughness) is integrated on its own, and a change of the model or of its parameters moves
    every row: a fifth of the rows is integrated again, each G another fifth (with the first
    and last rows)."""
    for k, g in enumerate(G_MODELS):
        rows = sorted({0, ibl_bake.DFG_SIZE - 1, *range(k, ibl_bake.DFG_SIZE, 5)})
        shipped = ibl_bake.shipped_dfg(g)
        assert shipped is not None, "addon/data lacks a DFG table for today's parameters"
        np.testing.assert_allclose(
            shipped[rows], ibl_bake.dfg_table(g, rows=rows), rtol=1e-6, atol=1e-7, err_msg=g
        )
        shipped = ibl_bake.shipped_dominant(g)
        assert shipped is not None, "addon/data lacks a dominant table for today's parameters"
        np.testing.assert_allclose(
            shipped[rows], ibl_bake.dominant_table(g, rows=rows), rtol=1e-6, atol=1e-7, err_msg=g
        )
    monkeypatch.setenv("CTLAB_CACHE", str(tmp_path / "empty-cache"))

    def no_integration(*args, **kw):
        raise AssertionError("the bake integrated a table it ships")

    monkeypatch.setattr(ibl_bake, "dfg_table", no_integration)
    monkeypatch.setattr(ibl_bake, "dominant_table", no_integration)
    path = tmp_path / "sky.exr"
    write_float_exr(path, np.ones((32, 64, 3), np.float32))
    folder = ibl_bake.bake(path)
    np.testing.assert_allclose(
        read_image(folder / ibl_bake.dfg_file("cook_torrance")),
        ibl_bake.shipped_dfg("cook_torrance"),
        rtol=1e-7,
    )
    np.testing.assert_allclose(
        read_image(folder / ibl_bake.ms_file("unity_smith_joint"))[..., 2],
        ibl_bake.shipped_dominant("unity_smith_joint"),
        rtol=1e-7,
    )


@pytest.mark.one_series  # numpy's integration, the same on every Blender series
def test_the_shipped_correction_tables_are_what_integrating_them_gives(tmp_path, monkeypatch):
    """The node group's correction tables (addon/core/correction_tables.py) ship too
    (addon/data/correction_tables.npz, scripts/build_tables.py): a first node group in an
    empty cache would otherwise integrate them for 7 s. They must equal a fresh integration
    of today's model and parameters: every row is integrated on its own and a change of the
    model moves every row, so a fifth of the rows (and the first and last) is integrated
    again; and an empty cache must write the shipped tables without integrating."""
    from addon.core import correction_tables as ct

    shipped = ct.shipped_tables()
    assert shipped is not None, "addon/data lacks correction tables for today's parameters"
    assert set(shipped) == set(ct.CORRECTION_TABLES)
    rows = sorted({0, ibl_bake.DFG_SIZE - 1, *range(2, ibl_bake.DFG_SIZE, 5)})
    for name, table in ct.all_tables(rows=rows).items():
        np.testing.assert_allclose(shipped[name][rows], table, rtol=1e-6, atol=1e-7, err_msg=name)
    monkeypatch.setenv("CTLAB_CACHE", str(tmp_path / "empty-cache"))

    def no_integration(*args, **kw):
        raise AssertionError("the cache integrated a table the extension ships")

    monkeypatch.setattr(ct, "all_tables", no_integration)
    folder = ct.correction_table_folder()
    for name in ("lobes_cook_torrance", "disney_negative"):
        np.testing.assert_array_equal(read_image(folder / f"{name}.exr"), shipped[name])


@pytest.mark.parametrize("g_model", ["cook_torrance", "smith_ggx_correlated"])
def test_the_dominant_direction_is_the_lobes_centroid(g_model):
    """The corrected split-sum's t (channel 2 of ms_<G>): normalize(mix(n, r, t)) must point
    at the centroid of f_s (n.l), here found by brute-force quadrature over l of the reference
    model's f_s (white metal, F = 1). Smith's t at full roughness is 0 (the centroid is n), as
    Lagarde and de Rousiers' fit says; the Cook-Torrance G's is not."""
    from reference_model import terms

    table = ibl_bake.dominant_table(g_model)
    n_theta, n_phi = 600, 300
    theta = (np.arange(n_theta) + 0.5) / n_theta * (np.pi / 2)
    phi = (np.arange(n_phi) + 0.5) / n_phi * 2 * np.pi
    T, P = np.meshgrid(theta, phi, indexing="ij")
    l = np.stack([np.sin(T) * np.cos(P), np.sin(T) * np.sin(P), np.cos(T)], axis=-1)
    n = np.broadcast_to(np.array([0.0, 0.0, 1.0]), l.shape)
    for j in (32, 48, 63):  # pr = j / 63
        pr = j / 63
        for i in (19, 38, 57):  # n.v = i / 63
            mu = i / 63
            v = np.array([np.sqrt(1 - mu * mu), 0.0, mu])
            fs = terms(
                n,
                v,
                l,
                np.ones(l.shape),
                np.ones(T.shape),
                np.full(T.shape, 1 - pr),
                g_model=g_model,
            )["specular_brdf"][..., 0]
            w = fs * np.cos(T) * np.sin(T)
            cx, cz = np.sum(w * l[..., 0]), np.sum(w * l[..., 2])
            tan_c = -cx / cz
            want = tan_c / (v[0] + tan_c * (1 - mu))
            assert abs(table[j, i] - np.clip(want, 0, 1)) < 0.02, (pr, mu, table[j, i], want)
    if g_model == "smith_ggx_correlated":
        assert table[63, :-1].max() < 0.02  # at n.v = 1, r = n: any t, 1 by convention
    else:
        assert table[63, 32] > 0.15
