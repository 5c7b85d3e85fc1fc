"""The tables of the node group's scene-transport correction: integrals of the model alone
(its G and diffuse against the closures Cycles offers), which the correction's lookups read.
Pure numpy. The extension ships them (addon/data/correction_tables.npz with
correction_tables.json, their parameters; scripts/build_tables.py), so that no first use
integrates them (7 s on two cores); a cache writes them as EXR files, integrated only where
the shipped file is absent or made for other parameters."""

from __future__ import annotations

import json
import zipfile

import numpy as np

from .ibl_bake import DFG_SIZE
from .model import G_MODELS

CORRECTION_VERSION = 1
CORRECTION_SAMPLES = (128, 64)  # GGX half vectors per n.v (ibl_bake.ggx_half_vectors)
CORRECTION_DIFFUSE_SAMPLES = (128, 64)  # cosine-distributed l: s by phi in [0, pi]
CORRECTION_TABLE_KINDS = ("residual", "positive", "lobes")
DISNEY_TABLES = ("disney_positive", "disney_negative")
CORRECTION_TABLES = (
    tuple(f"{kind}_{g}" for kind in CORRECTION_TABLE_KINDS for g in G_MODELS) + DISNEY_TABLES
)


def kernel_mean_cosines() -> np.ndarray:
    """The mean cosine to its axis of each pre-filtered level's kernel (level 0 is the HDRI
    itself: 1), K(mu) = D(h) mu over mu = r.l in [0, 1] (latlong.ggx_kernel), by quadrature
    in q = (1 - mu)/2, denser toward the peak."""
    from ..core.ibl_bake import LEVEL_ROUGHNESS
    from ..core.latlong import ggx_kernel
    from ..core.model import ggx_alpha

    s = (np.arange(20000) + 0.5) / 20000
    q, dq = 0.5 * s**4, 2.0 * s**3 / 20000
    out = [1.0]
    for pr in LEVEL_ROUGHNESS[1:]:
        k = ggx_kernel(ggx_alpha(pr))(q) * dq
        out.append(float(np.sum(k * (1 - 2 * q)) / np.sum(k)))
    return np.array(out)


def correction_tables(g_model: str, size: int | None = None, rows=None) -> dict:
    """The tables above for one G: {kind: (size, size, 3) float32}. ``rows``: only those
    rows j (one perceptual roughness each, integrated on its own), in that order."""
    from ..core.ibl_bake import DFG_MIN_NDOTV, dfg_axis, ggx_half_vectors
    from ..core.model import ggx_alpha

    size = size or DFG_SIZE
    x = dfg_axis(size)
    nv = np.maximum(x, DFG_MIN_NDOTV)
    rows = range(size) if rows is None else list(rows)
    tables = {kind: np.zeros((len(rows), size, 3)) for kind in CORRECTION_TABLE_KINDS}
    rbar = kernel_mean_cosines()

    def smith(nl, nv_, a):
        a2 = a * a
        return (
            2.0
            * nl
            * nv_
            / np.maximum(
                nl * np.sqrt(nv_ * nv_ * (1 - a2) + a2) + nv_ * np.sqrt(nl * nl * (1 - a2) + a2),
                1e-30,
            )
        )

    disney = disney_tables(size, rows)
    tables["residual"][..., 2] = (
        disney["disney_positive"][..., 0] + disney["disney_negative"][..., 0]
    )
    for j, pr in enumerate(x[rows]):
        if g_model == "smith_ggx_correlated":
            continue
        a = ggx_alpha(pr)
        q = ggx_half_vectors(nv, a, *CORRECTION_SAMPLES)
        nh, sh, vh, nl, sv = (q[k] for k in ("nh", "sh", "vh", "nl", "sv"))
        nv3 = nv[:, None, None]
        if g_model == "unity_smith_joint":
            g = 2.0 * nl * nv3 / (nl * (nv3 * (1 - a) + a) + nv3 * (nl * (1 - a) + a) + 1e-5)
        else:
            g = np.minimum(1.0, 2.0 * nh * np.minimum(nv3, nl) / np.maximum(vh, 1e-12))
        dg = g - smith(nl, nv3, a)
        fc = (1.0 - vh) ** 5
        # l in the plane of n and v: toward the mirror side, along n (ibl_bake's centroid)
        l_x = -(2.0 * vh * sh * np.cos(q["phi"]) - sv)
        parts = {}
        for sign, part in ((1, "+"), (-1, "-")):
            w = np.maximum(sign * dg, 0.0) * vh / (nh * nv3) * q["weight"]
            total = np.sum(w, axis=(1, 2))
            cx, cz = np.sum(w * l_x, axis=(1, 2)), np.sum(w * nl, axis=(1, 2))
            parts[part] = (
                np.sum(w * (1.0 - fc), axis=(1, 2)),
                np.sum(w * fc, axis=(1, 2)),
                *_lobe(total, cx, cz, rbar),
            )
        (a_p, b_p, c_p, x_p), (a_m, b_m, c_m, x_m) = parts["+"], parts["-"]
        tables["residual"][j, :, 0], tables["residual"][j, :, 1] = a_p + a_m, b_p + b_m
        tables["positive"][j] = np.stack([a_p, b_p, c_p], axis=-1)
        tables["lobes"][j] = np.stack([x_p, c_m, x_m], axis=-1)
    return {kind: t.astype(np.float32) for kind, t in tables.items()}


def _lobe(total, cx, cz, rbar):
    """A part's centroid angle from n (toward the mirror side) and its level, from its
    weight and first moments (x toward the mirror side, z along n)."""
    mean_cos = np.where(total > 0, np.hypot(cx, cz) / np.maximum(total, 1e-30), 1.0)
    angle = np.where(total > 0, np.arctan2(cx, np.maximum(cz, 1e-30)), 0.0)
    return angle, np.interp(-np.minimum(mean_cos, 1.0), -rbar, np.arange(len(rbar), dtype=float))


def disney_tables(size: int | None = None, rows=None) -> dict:
    """The tables of Disney's diffuse minus Lambert's above: {name: (size, size, 3)}, by a
    midpoint grid over cosine-distributed l (Malley's method; v in the xz plane, phi in
    [0, pi] by symmetry), (l.h)^2 = (1 + l.v)/2. ``rows`` as in correction_tables."""
    from ..core.ibl_bake import DFG_MIN_NDOTV, dfg_axis

    size = size or DFG_SIZE
    x = dfg_axis(size)
    nv = np.maximum(x, DFG_MIN_NDOTV)[:, None, None]
    rbar = kernel_mean_cosines()
    ns, nphi = CORRECTION_DIFFUSE_SAMPLES
    s = ((np.arange(ns) + 0.5) / ns)[None, :, None]
    phi = ((np.arange(nphi) + 0.5) / nphi * np.pi)[None, None, :]
    lx, lz = np.sqrt(s) * np.cos(phi), np.sqrt(1.0 - s)
    lv = lx * np.sqrt(1.0 - nv * nv) + lz * nv  # v = (sin, 0, n.v)
    rows = range(size) if rows is None else list(rows)
    tables = {name: np.zeros((len(rows), size, 3)) for name in DISNEY_TABLES}
    for j, pr in enumerate(x[rows]):
        fd90_m1 = pr * (1.0 + lv) - 0.5
        d = (1 + fd90_m1 * (1 - lz) ** 5) * (1 + fd90_m1 * (1 - nv) ** 5) - 1.0
        for sign, name in ((1, "disney_positive"), (-1, "disney_negative")):
            w = np.maximum(sign * d, 0.0) / (ns * nphi)
            total = np.sum(w, axis=(1, 2))
            cx, cz = np.sum(w * -lx, axis=(1, 2)), np.sum(w * lz, axis=(1, 2))
            tables[name][j] = np.stack([total, *_lobe(total, cx, cz, rbar)], axis=-1)
    return {name: t.astype(np.float32) for name, t in tables.items()}


def all_tables(rows=None) -> dict:
    """Every table of CORRECTION_TABLES by name, integrated (``rows`` as in
    correction_tables)."""
    out = {}
    for g in G_MODELS:
        for kind, table in correction_tables(g, rows=rows).items():
            out[f"{kind}_{g}"] = table
    out.update(disney_tables(rows=rows))
    return out


SHIPPED = "correction_tables"  # addon/data/<SHIPPED>.npz and .json


def table_signature() -> dict:
    """What the tables depend on besides the model's formulas: a shipped file is used only
    when this matches (a change of the formulas is caught by tests/render/test_ibl_bake.py,
    which integrates rows again)."""
    from ..core.ibl_bake import DFG_MIN_NDOTV, LEVEL_ROUGHNESS

    return {
        "version": CORRECTION_VERSION,
        "size": DFG_SIZE,
        "min_ndotv": DFG_MIN_NDOTV,
        "samples": list(CORRECTION_SAMPLES),
        "diffuse_samples": list(CORRECTION_DIFFUSE_SAMPLES),
        "level_roughness": [float(r) for r in LEVEL_ROUGHNESS],
        "tables": list(CORRECTION_TABLES),
    }


def shipped_tables() -> dict | None:
    """The shipped tables by name, or None when absent, damaged, of another shape or made
    for other parameters."""
    from .files import DATA_DIR

    try:
        meta = json.loads((DATA_DIR / f"{SHIPPED}.json").read_text())
        with np.load(DATA_DIR / f"{SHIPPED}.npz") as npz:
            tables = {name: npz[name] for name in CORRECTION_TABLES}
    except (OSError, ValueError, KeyError, zipfile.BadZipFile):
        return None
    if meta != table_signature():
        return None
    if any(t.shape != (DFG_SIZE, DFG_SIZE, 3) for t in tables.values()):
        return None
    return {name: t.astype(np.float32) for name, t in tables.items()}


def correction_table_folder():
    """The folder of the tables above (<kind>_<G>.exr for every kind and G), in the cache:
    they depend on the model alone, the shipped ones (shipped_tables) or, without them,
    integrated once per cache (7 s)."""
    from ..core import cache
    from ..core.hdri import write_float_exr

    key = (
        f"correction-v{CORRECTION_VERSION}-{DFG_SIZE}-{CORRECTION_SAMPLES[0]}x"
        f"{CORRECTION_SAMPLES[1]}-{CORRECTION_DIFFUSE_SAMPLES[0]}x"
        f"{CORRECTION_DIFFUSE_SAMPLES[1]}"
    )

    def fill(stage):
        for name, table in (shipped_tables() or all_tables()).items():
            write_float_exr(stage / f"{name}.exr", table)

    return cache.cached(key, fill)
