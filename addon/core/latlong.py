"""Lat-long images as Blender's Environment Texture maps them, and convolution with a zonal
kernel on them (the split-sum bake, core/ibl_bake.py; the importance tables,
core/env_importance.py; the correction tables, core/correction_tables.py).

Row 0 is the top (elevation +pi/2); a texel covers (2 pi / w)(sin e_top - sin e_bottom) sr.
For an output row at elevation e and a source row at e', a zonal kernel depends on the
longitude difference alone, so each pair of rows is a circular convolution along the row,
done with real FFTs.
"""

from __future__ import annotations

import numpy as np

# ---------------------------------------------------------------------------------------
# The lat-long grid (Blender's Environment Texture: row 0 is the top, elevation +pi/2)


def row_elevations(h: int) -> np.ndarray:
    """Elevation of each row's centre, top row first."""
    return np.pi / 2 - (np.arange(h) + 0.5) * np.pi / h


def row_solid_angles(h: int, w: int) -> np.ndarray:
    """Solid angle of one texel in each row: (2 pi / w)(sin e_top - sin e_bottom)."""
    edges = np.pi / 2 - np.arange(h + 1) * np.pi / h
    return (2 * np.pi / w) * (np.sin(edges[:-1]) - np.sin(edges[1:]))


def area_resample(a: np.ndarray, n: int, axis: int, weights: np.ndarray | None) -> np.ndarray:
    """Area-average ``a`` along ``axis`` onto n equal bins (texels are constant over their
    extent; ``weights`` the measure of each source texel, e.g. its solid angle)."""
    a = np.moveaxis(a, axis, 0).astype(np.float64)
    N = a.shape[0]
    w = np.ones(N) if weights is None else np.asarray(weights, dtype=np.float64)
    shape = (N,) + (1,) * (a.ndim - 1)
    cum_a = np.concatenate([np.zeros((1,) + a.shape[1:]), np.cumsum(a * w.reshape(shape), axis=0)])
    cum_w = np.concatenate([[0.0], np.cumsum(w)])
    x = np.arange(n + 1) * (N / n)
    i = np.minimum(np.floor(x).astype(int), N - 1)
    f = (x - i).reshape((n + 1,) + (1,) * (a.ndim - 1))
    ca = cum_a[i] + f * (a[i] * w[i].reshape((n + 1,) + (1,) * (a.ndim - 1)))
    cw = cum_w[i] + f.reshape(-1) * w[i]
    out = (ca[1:] - ca[:-1]) / (cw[1:] - cw[:-1]).reshape((n,) + (1,) * (a.ndim - 1))
    return np.moveaxis(out.astype(np.float32), 0, axis)


def downsample(img: np.ndarray, w: int) -> np.ndarray:
    """The lat-long image at w x w/2, each texel the solid-angle-weighted mean of the source."""
    H, W = img.shape[:2]
    h = w // 2
    if W == w:
        return img.astype(np.float32)
    dw = row_solid_angles(H, W)
    if H % h == 0 and W % w == 0:  # whole blocks: a weighted block mean
        fy, fx = H // h, W // w
        weighted = (img * dw[:, None, None].astype(np.float32)).reshape(h, fy, w, fx, 3)
        return (
            weighted.sum(axis=(1, 3)) / (dw.reshape(h, fy).sum(axis=1)[:, None, None] * fx)
        ).astype(np.float32)
    return area_resample(area_resample(img, h, 0, dw), w, 1, None)


# ---------------------------------------------------------------------------------------
# Zonal convolution


def ggx_kernel(alpha: float):
    """K(q) = D(h) max(mu, 0) with mu = r.l = 1 - 2q; (n.h)^2 = 1 - q, so the GGX denominator
    (n.h)^2 (a^2 - 1) + 1 = q + a^2 (1 - q) has no cancellation near the lobe's peak."""
    a2 = alpha * alpha

    def K(q):
        d = q + a2 * (1.0 - q)
        return (a2 / np.pi) / (d * d) * np.maximum(1.0 - 2.0 * q, 0.0)

    return K


def cosine_kernel(q):
    """K(q) = max(n.l, 0) with n.l = 1 - 2q."""
    return np.maximum(1.0 - 2.0 * q, 0.0)


def zonal_convolve(src: np.ndarray, kernel, normalize: bool, chunk: int = 16) -> np.ndarray:
    """out(r) = sum_l K(r.l) L(l) dw_l over the lat-long image src (h, w, 3); divided by
    sum_l K(r.l) dw_l when ``normalize``. Output on the same grid.

    For rows at elevations e, e' and longitude difference dphi,
    q = (1 - r.l)/2 = sin^2((e - e')/2) + cos e cos e' sin^2(dphi/2) (no cancellation).
    A normalised convolution with a kernel >= 0 cannot leave [min(src), max(src)]: the FFT's
    round-off (which put -1e-13 beside a 10^6 texel) is clipped to that range."""
    h, w, _ = src.shape
    elev = row_elevations(h)
    dw = row_solid_angles(h, w)
    sin2_half_dphi = (np.sin(np.pi * np.arange(w) / w) ** 2).astype(np.float32)  # dphi = 2 pi k / w
    src_hat = np.fft.rfft(src.astype(np.float64) * dw[:, None, None], axis=1)  # (h, f, 3)
    out = np.empty((h, w, 3), dtype=np.float32)
    for i0 in range(0, h, chunk):
        rows = np.arange(i0, min(h, i0 + chunk))
        de = elev[rows][:, None] - elev[None, :]  # (c, h)
        a = (np.sin(de / 2) ** 2).astype(np.float32)
        b = (np.cos(elev[rows])[:, None] * np.cos(elev)[None, :]).astype(np.float32)
        q = a[:, :, None] + b[:, :, None] * sin2_half_dphi[None, None, :]  # (c, h, w)
        k = kernel(q).astype(np.float32)
        k_hat = np.fft.rfft(k, axis=2)  # (c, h, f)
        acc = np.einsum("cjf,jfk->cfk", k_hat, src_hat)
        res = np.fft.irfft(acc, n=w, axis=1)  # (c, w, 3)
        if normalize:
            total = (k_hat[:, :, 0].real * dw[None, :]).sum(axis=1)  # (c,)
            res = res / np.maximum(total, 1e-30)[:, None, None]
        out[rows] = res
    if normalize:
        np.clip(out, min(float(src.min()), 0.0), float(src.max()), out=out)
    return out
