"""Split-sum image-based lighting (Karis 2013, "Real Shading in Unreal Engine 4"): the bake.

From a scene-linear equirectangular HDRI this writes, as float EXR:

- ``specular_<m>.exr``, m = 0 .. 6: the radiance pre-filtered with this model's GGX lobe under
  the split-sum's n = v = r assumption, at perceptual roughness pr_m = m / 6 (Unity's seven
  reflection-probe mip levels, UNITY_SPECCUBE_LOD_STEPS = 6). With n = v = r and l drawn from
  D(h)(n.h) the pdf of l is D(h)/4, so Karis's estimator sum L(l)(n.l) / sum (n.l) converges to
  the normalised convolution

      P(r) = integral L(l) K(r.l) dl / integral K(r.l) dl,   K(mu) = D(h) max(mu, 0),
      (n.h)^2 = (1 + mu) / 2,

  which is computed here exactly (no sampling, so a bright sun cannot speckle) on a lat-long
  grid whose resolution falls with the lobe's width. Level 0 (alpha = 0.002, a lobe narrower
  than a texel of a 2k map) is the source itself.
- ``irradiance.exr``: E(n) = integral L(l) max(n.l, 0) dl, the cosine convolution (stored as E,
  so a uniform world of radiance 1 gives pi; Lambert's reflected radiance is diffColor E / pi).
- ``dfg_<g_model>.exr``: for (n.v, pr) the scale A and bias B of specColor in the directional
  albedo of f_s, integral f_s (n.l) dl = specColor A + B, with this model's D and G, and in the
  third channel the Disney-diffuse factor: the cosine-weighted mean over l of Burley's
  (1 + (fd90 - 1)(1 - n.l)^5)(1 + (fd90 - 1)(1 - n.v)^5) (1 for Lambert).
  Texel (i, j): n.v = i / (N - 1) (column 0 at n.v = 1e-3), pr = j / (N - 1); row j = 0 is the
  top of the image. The grid includes both ends (pr = 1 is the matrix's bottom row), so a
  bilinear lookup at s = (n.v (N - 1) + 0.5) / N, t = (pr (N - 1) + 0.5) / N never clamps.

The convolutions are zonal, on the lat-long grid (core/latlong.py).
"""

from __future__ import annotations

import json
import shutil
import time
from pathlib import Path

import numpy as np

from . import cache
from .files import DATA_DIR, write_json
from .gate import Gate
from .hdri import file_hash, load_hdri, write_float_exr
from .latlong import cosine_kernel, downsample, ggx_kernel, zonal_convolve
from .model import G_MODELS, ggx_alpha

VERSION = 5  # 4: the multiple-scattering tables (ms_<G>.exr); 5: their dominant direction
LEVEL_COUNT = 7
LEVEL_ROUGHNESS = tuple(m / (LEVEL_COUNT - 1) for m in range(LEVEL_COUNT))
# Width of each pre-filtered level (0: the source's own); the lobe's half-width spans >= 3 texels.
LEVEL_WIDTHS = (0, 512, 256, 128, 64, 64, 64)
IRRADIANCE_WIDTH = 128
DFG_SIZE = 64
# Quadrature grid per table entry (GGX inverse CDF, azimuth); Cook-Torrance's min() has kinks
# in azimuth that need the finer grid. Both stay within 4e-4 of a 16x finer grid.
DFG_SAMPLES = {
    "cook_torrance": (256, 128),
    "smith_ggx_correlated": (256, 64),
    "unity_smith_joint": (256, 64),
}


def level_file(m: int) -> str:
    return f"specular_{m}.exr"


DFG_MIN_NDOTV = 1e-3


def dfg_axis(size: int = DFG_SIZE) -> np.ndarray:
    """The DFG table's sample positions along both axes: 0 .. 1, ends included."""
    return np.linspace(0.0, 1.0, size)


def dfg_file(g_model: str) -> str:
    return f"dfg_{g_model}.exr"


IRRADIANCE_FILE = "irradiance.exr"
INFO_FILE = "bake.json"


# ---------------------------------------------------------------------------------------
# The DFG table (independent of the HDRI: cached once per model version)


def ggx_half_vectors(nv: np.ndarray, a: float, nu: int, nphi: int) -> dict:
    """The quadrature of the DFG table, for any integrand g(h) over GGX half vectors:
    Σ g(h) weight ≈ ∫ g(h) D(h) (n.h) dω_h over the half vectors whose mirror l of v lies
    above the horizon, for g symmetric about the plane of n and v (n = z, v in xz).

    Half vectors h follow D(h)(n.h) (Walter et al. 2007, eq. 35-36: tan^2 theta_h =
    a^2 u / (1 - u)). Quadrature, not sampling: u = 1 - (1 - s)^3 on a midpoint grid in s
    (fine where the GGX tail meets the horizon), and for each u the azimuths that keep l above
    the horizon, 0 <= phi < phi_max, where
    n.l = 2 (v.h)(n.h) - n.v > 0  <=>  cos phi > (n.v / (2 n.h) - (n.v)(n.h)) / (sin_v sin_h);
    so the integrand has no discontinuity inside the grid. Arrays of shape (len(nv), nu, nphi)
    (broadcast): nh, sh (sin theta_h), phi, vh, nl, sv (sin theta_v) and weight."""
    s = (np.arange(nu) + 0.5) / nu
    u = (1.0 - (1.0 - s) ** 3)[None, :, None]
    du = (3.0 * (1.0 - s) ** 2)[None, :, None]
    nv = nv[:, None, None]
    sv = np.sqrt(1.0 - nv * nv)
    nh = 1.0 / np.sqrt(1.0 + a * a * u / (1.0 - u))
    sh = np.sqrt(np.maximum(0.0, 1.0 - nh * nh))
    num = nv / (2.0 * nh) - nv * nh
    den = sv * sh
    c0 = np.where(den > 0, num / np.where(den > 0, den, 1.0), np.where(num < 0, -1.0, 2.0))
    phi_max = np.where(c0 <= 1.0, np.arccos(np.clip(c0, -1.0, 1.0)), 0.0)
    phi = ((np.arange(nphi) + 0.5) / nphi)[None, None, :] * phi_max
    vh = np.clip(sv * sh * np.cos(phi) + nv * nh, 0.0, 1.0)
    nl = np.clip(2.0 * vh * nh - nv, 0.0, 1.0)
    return {
        "nh": nh,
        "sh": sh,
        "phi": phi,
        "vh": vh,
        "nl": nl,
        "sv": sv,
        "weight": du * phi_max / (np.pi * nu * nphi),
    }


def _specular_scale_bias(
    g_model: str, nv: np.ndarray, pr: float, nu: int, nphi: int, centroid: bool = False
):
    """A(n.v), B(n.v) at one perceptual roughness: integral f_s (n.l) dl = F0 A + B, each
    half vector of ggx_half_vectors adding F G (v.h) / ((n.h)(n.v)) (Karis 2013), with
    F = F0 (1 - Fc) + Fc, Fc = (1 - v.h)^5."""
    a = ggx_alpha(pr)
    q = ggx_half_vectors(nv, a, nu, nphi)
    nh, sh, phi, vh, nl, sv = (q[k] for k in ("nh", "sh", "phi", "vh", "nl", "sv"))
    nv = nv[:, None, None]
    if g_model == "smith_ggx_correlated":
        G = (
            2.0
            * nl
            * nv
            / np.maximum(
                nl * np.sqrt(nv * nv * (1 - a * a) + a * a)
                + nv * np.sqrt(nl * nl * (1 - a * a) + a * a),
                1e-30,
            )
        )
    elif g_model == "unity_smith_joint":
        G = 2.0 * nl * nv / (nl * (nv * (1 - a) + a) + nv * (nl * (1 - a) + a) + 1e-5)
    else:
        G = np.minimum(1.0, 2.0 * nh * np.minimum(nv, nl) / np.maximum(vh, 1e-12))
    weight = G * vh / (nh * nv) * q["weight"]
    fc = (1.0 - vh) ** 5
    if centroid:
        # the lobe's f_s (n.l) centroid (F = 1) in the plane of n and v: x toward the mirror
        # side, z along n (l = 2 (v.h) h - v; the lobe is symmetric in y)
        lx = 2.0 * vh * sh * np.cos(phi) - sv
        return np.sum(weight * lx, axis=(1, 2)), np.sum(weight * nl, axis=(1, 2))
    return np.sum(weight * (1.0 - fc), axis=(1, 2)), np.sum(weight * fc, axis=(1, 2))


def _disney_factor(nv: np.ndarray, pr: float, n: int = 64) -> np.ndarray:
    """Mean of Burley's (1 + (fd90 - 1)(1 - n.l)^5)(1 + (fd90 - 1)(1 - n.v)^5) over
    cosine-distributed l (Malley's method, midpoint grid), fd90 = 0.5 + 2 (l.h)^2 pr."""
    s = ((np.arange(n) + 0.5) / n)[None, :, None]
    phi = ((np.arange(2 * n) + 0.5) / (2 * n) * 2 * np.pi)[None, None, :]
    lx, ly, lz = np.sqrt(s) * np.cos(phi), np.sqrt(s) * np.sin(phi), np.sqrt(1.0 - s)
    nv = nv[:, None, None]
    hx, hz = lx + np.sqrt(1.0 - nv * nv), lz + nv
    lh = np.clip((lx * hx + ly * ly + lz * hz) / np.sqrt(hx * hx + ly * ly + hz * hz), 0.0, 1.0)
    fd90 = 0.5 + 2.0 * lh * lh * pr
    return np.mean((1 + (fd90 - 1) * (1 - lz) ** 5) * (1 + (fd90 - 1) * (1 - nv) ** 5), axis=(1, 2))


def dfg_table(g_model: str, size: int = DFG_SIZE, samples=None, rows=None) -> np.ndarray:
    """(size, size, 3) float32: row j is pr = j/(size - 1), column i is n.v = i/(size - 1)
    (n.v >= DFG_MIN_NDOTV); channels: A, B (specColor scale and bias), the Disney factor.
    ``rows``: only those rows j, in that order (each row is integrated on its own)."""
    samples = samples or DFG_SAMPLES[g_model]
    x = dfg_axis(size)
    nv = np.maximum(x, DFG_MIN_NDOTV)
    rows = range(size) if rows is None else list(rows)
    table = np.zeros((len(rows), size, 3))
    for k, j in enumerate(rows):
        table[k, :, 0], table[k, :, 1] = _specular_scale_bias(g_model, nv, x[j], *samples)
        table[k, :, 2] = _disney_factor(nv, x[j])
    return table.astype(np.float32)


# ---------------------------------------------------------------------------------------
# The bake: cached by the HDRI's content hash and the bake parameters


def _params_key() -> str:
    import hashlib

    sig = json.dumps([VERSION, LEVEL_WIDTHS, IRRADIANCE_WIDTH, DFG_SIZE, DFG_SAMPLES])
    return hashlib.sha256(sig.encode()).hexdigest()[:8]


# The DFG tables depend on the model alone, so the extension ships them (addon/data/, written
# by scripts/build_tables.py; tests/render/test_ibl_bake.py checks that integrating them again gives
# the same values): a first bake reads them instead of integrating for seconds.


def table_signature() -> dict:
    """What the DFG tables depend on: a shipped table is used only when this matches."""
    return {
        "version": VERSION,
        "size": DFG_SIZE,
        "min_ndotv": DFG_MIN_NDOTV,
        "samples": {g: list(s) for g, s in DFG_SAMPLES.items()},
    }


def _shipped(name: str, shape: tuple) -> np.ndarray | None:
    """A table the extension ships (addon/data/NAME.npy, scripts/build_tables.py), or None
    when absent, of another shape or made for other parameters (dfg.json)."""
    try:
        meta = json.loads((DATA_DIR / "dfg.json").read_text())
        table = np.load(DATA_DIR / f"{name}.npy")
    except (OSError, ValueError):
        return None
    if meta != table_signature() or table.shape != shape:
        return None
    return table.astype(np.float32)


def shipped_dfg(g_model: str) -> np.ndarray | None:
    """The shipped DFG table of one G option, or None (_shipped)."""
    return _shipped(f"dfg_{g_model}", (DFG_SIZE, DFG_SIZE, 3))


def shipped_dominant(g_model: str) -> np.ndarray | None:
    """The shipped dominant-direction table of one G option, or None (_shipped)."""
    return _shipped(f"dominant_{g_model}", (DFG_SIZE, DFG_SIZE))


def dfg_values(g_model: str) -> np.ndarray:
    """The DFG table of one G option: the shipped one, else integrated."""
    table = shipped_dfg(g_model)
    return dfg_table(g_model) if table is None else table


def dominant_values(g_model: str) -> np.ndarray:
    """The dominant-direction table of one G option: the shipped one, else integrated (12 s
    for the three G options on two cores)."""
    table = shipped_dominant(g_model)
    return dominant_table(g_model) if table is None else table


def dominant_table(g_model: str, size: int = DFG_SIZE, rows=None) -> np.ndarray:
    """(size, size): per (n.v, pr) on the DFG table's axes, the t for which
    normalize(mix(n, r, t)) points at the centroid of the lobe f_s (n.l) (F = 1) of this D and
    G: the split-sum's dominant direction computed for the model, where Lagarde and de Rousiers
    (2014, listing 22) fit t = (1 - a)(sqrt(1 - a) + a) to Smith's G. With the centroid at
    angle c from n and r at angle theta_v: tan c = t sin / (1 - t + t cos), so
    t = tan c / (sin theta_v + tan c (1 - cos theta_v)). ``rows``: as dfg_table's."""
    x = dfg_axis(size)
    nv = np.maximum(x, DFG_MIN_NDOTV)
    sv = np.sqrt(1.0 - nv * nv)
    rows = range(size) if rows is None else list(rows)
    table = np.ones((len(rows), size))
    for k, j in enumerate(rows):
        cx, cz = _specular_scale_bias(g_model, nv, x[j], *DFG_SAMPLES[g_model], centroid=True)
        tan_c = -cx / np.maximum(cz, 1e-12)
        den = sv + tan_c * (1.0 - nv)
        table[k] = np.where(den > 1e-6, tan_c / np.where(den > 1e-6, den, 1.0), 1.0)
    return np.clip(table, 0.0, 1.0).astype(np.float32)


def ms_table(dfg: np.ndarray, dominant: np.ndarray) -> np.ndarray:
    """The multiple-scattering table (Kulla and Conty 2017) from a DFG table, same axes:
    channel 0 is E(n.v, pr) = A + B, the directional albedo of the single-scattering specular
    lobe with F = 1; channel 1 is E_avg(pr) = 2 integral_0^1 E(mu) mu dmu (trapezoids over the
    table's columns), the same along a row; channel 2 is the dominant direction's t
    (dominant_table)."""
    E = np.clip(dfg[..., 0] + dfg[..., 1], 0.0, 1.0).astype(np.float64)
    mu = np.maximum(dfg_axis(dfg.shape[1]), DFG_MIN_NDOTV)
    e_avg = 2.0 * np.sum(0.5 * (E[:, 1:] * mu[1:] + E[:, :-1] * mu[:-1]) * np.diff(mu), axis=1)
    table = np.zeros(dfg.shape, np.float32)
    table[..., 0] = E
    table[..., 1] = np.clip(e_avg, 0.0, 1.0)[:, None]
    table[..., 2] = dominant
    return table


def tables_folder() -> Path:
    """The model's HDRI-independent tables in the cache, one folder: dfg_<G>.exr and
    ms_<G>.exr for every G option (the OSL shader's energy compensation reads them)."""
    key = f"tables-v{VERSION}-{DFG_SIZE}-" + "-".join(
        f"{g}{s[0]}x{s[1]}" for g, s in DFG_SAMPLES.items()
    )

    def fill(stage):
        for g in G_MODELS:
            dfg = dfg_values(g)
            write_float_exr(stage / dfg_file(g), dfg)
            write_float_exr(stage / ms_file(g), ms_table(dfg, dominant_values(g)))

    return cache.cached(key, fill)


def ms_file(g_model: str) -> str:
    return f"ms_{g_model}.exr"


def dfg_path(g_model: str) -> Path:
    """The DFG table of one G option (independent of the HDRI) in the cache: the shipped one,
    or integrated once per cache when none matches."""
    size, samples = DFG_SIZE, DFG_SAMPLES[g_model]
    key = f"dfg-v{VERSION}-{g_model}-{size}-{samples[0]}x{samples[1]}"

    def fill(stage):
        write_float_exr(stage / "dfg.exr", dfg_values(g_model))

    return cache.cached(key, fill) / "dfg.exr"


def _report(progress, fraction, message):
    if progress is not None:
        progress(fraction, message)


def bake(hdri_path, progress=None, warn=None) -> Path:
    """Bake (or find in the cache) the split-sum files for an HDRI; returns their folder.

    ``progress(fraction, message)`` is called as the work advances, ``warn(message)`` for
    repaired input. Raises UserError for unusable input (hdri.read_hdri)."""
    from .hdri import read_hdri

    hdri_path = Path(hdri_path)
    if not hdri_path.is_file():
        load_hdri(hdri_path)  # raises the standard "not found" message
    source_hash = file_hash(hdri_path)
    name = f"ibl-v{VERSION}-{_params_key()}-{source_hash}"
    folder = cache.lookup(name)
    if folder is not None:
        _report(progress, 1.0, f"cached: {folder}")
        return folder
    # validates before any write; NaN/Inf texels are refused, as by every job (one rule,
    # docs/bad-input.md: the render reads the same file and would carry them)
    pixels, repaired = read_hdri(hdri_path)
    dfg = {}
    tables = tables_folder()
    for g in G_MODELS:
        _report(progress, 0.05, f"DFG table ({g}; once per cache)")
        dfg[g] = dfg_path(g)
    start = time.perf_counter()  # the HDRI's own bake, after the shared DFG tables
    timings = {}

    def fill(stage: Path):
        H, W = pixels.shape[:2]
        sources = {}
        levels = []
        for m, pr in enumerate(LEVEL_ROUGHNESS):
            _report(
                progress, 0.1 + 0.75 * m / LEVEL_COUNT, f"specular level {m} (roughness {pr:.3f})"
            )
            t = time.perf_counter()
            if m == 0:
                level = pixels
            else:
                w = min(LEVEL_WIDTHS[m], W)
                if w not in sources:
                    sources[w] = downsample(pixels, w)
                level = zonal_convolve(sources[w], ggx_kernel(ggx_alpha(pr)), True)
            write_float_exr(stage / level_file(m), level)
            timings[level_file(m)] = round(time.perf_counter() - t, 3)
            levels.append(
                {
                    "file": level_file(m),
                    "perceptual_roughness": pr,
                    "width": level.shape[1],
                    "height": level.shape[0],
                }
            )
        _report(progress, 0.9, "irradiance")
        t = time.perf_counter()
        w = min(IRRADIANCE_WIDTH, W)
        src = sources.get(w)
        if src is None:
            src = downsample(pixels, w)
        irr = np.pi * zonal_convolve(src, cosine_kernel, True)  # integral max(n.l,0) dl = pi
        write_float_exr(stage / IRRADIANCE_FILE, irr)
        timings[IRRADIANCE_FILE] = round(time.perf_counter() - t, 3)
        for g, path in dfg.items():
            shutil.copyfile(path, stage / dfg_file(g))
            shutil.copyfile(tables / ms_file(g), stage / ms_file(g))
        info = {
            "version": VERSION,
            "source": str(hdri_path),
            "source_hash": source_hash,
            "source_size": [W, H],
            "repaired_texels": repaired,
            "levels": levels,
            "irradiance": {
                "file": IRRADIANCE_FILE,
                "width": irr.shape[1],
                "height": irr.shape[0],
                "stores": "E (uniform radiance 1 gives pi)",
            },
            "dfg": {g: dfg_file(g) for g in dfg},
            "dfg_size": DFG_SIZE,
            "dfg_axes": "column i: n.v = i/(N-1) (column 0: n.v = 1e-3); row j (top "
            "first): pr = j/(N-1); look up at ((x (N-1) + 0.5)/N)",
            "dfg_channels": ["A (specColor scale)", "B (bias)", "Disney diffuse factor"],
            "ms": {g: ms_file(g) for g in dfg},
            "ms_channels": ["E = A + B (F = 1)", "E_avg", "0"],
            "seconds": round(time.perf_counter() - start, 3),
            "timings": timings,
        }
        write_json(stage / INFO_FILE, info)

    folder = cache.build(name, fill)
    _report(progress, 1.0, f"baked in {time.perf_counter() - start:.2f} s: {folder}")
    return folder


def file_names() -> list:
    """The files of a bake, as ``export`` copies them."""
    return (
        [level_file(m) for m in range(LEVEL_COUNT)]
        + [IRRADIANCE_FILE, INFO_FILE]
        + [dfg_file(g) for g in G_MODELS]
        + [ms_file(g) for g in G_MODELS]
    )


def export(folder: Path, out_dir: Path, source=None, force: bool = False) -> None:
    """Copy a bake folder's files into out_dir through its write gate (core.gate: all whole
    or none, never over the ``source`` HDRI, never over a file ctlab did not write there
    unless ``force``, never through a link)."""
    files = sorted(
        f for f in Path(folder).iterdir() if not f.name.startswith(".") and f.name != cache.MANIFEST
    )

    def copy(src: Path):
        return lambda tmp: shutil.copyfile(src, tmp)

    gate = Gate(out_dir, "the bake's files", force=force)
    gate.write({f.name: copy(f) for f in files}, inputs=[source] if source else [])
