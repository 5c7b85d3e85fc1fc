"""An independent numpy reference of docs/model.md (written from the document, not from the
OSL source), evaluated in float64 at given normals, for checking rendered views."""

import numpy as np


def _dot(a, b):
    return np.sum(a * b, axis=-1)


def _normalize(x):
    return x / np.linalg.norm(x, axis=-1, keepdims=True)


def terms(n, v, l, albedo, metallic, smoothness, g_model="cook_torrance", diffuse="disney"):
    """All term views at normals n (..., 3); v, l unit 3-vectors; per-pixel albedo (..., 3),
    metallic and smoothness (...)."""
    n = np.asarray(n, dtype=np.float64)
    v = np.broadcast_to(np.asarray(v, dtype=np.float64), n.shape)
    l = np.broadcast_to(np.asarray(l, dtype=np.float64), n.shape)
    albedo = np.asarray(albedo, dtype=np.float64)
    metallic = np.asarray(metallic, dtype=np.float64)[..., None]
    pr = 1.0 - np.asarray(smoothness, dtype=np.float64)
    alpha = np.maximum(pr**2, 0.002)
    spec = 0.04 * (1 - metallic) + albedo * metallic
    diff = albedo * 0.96 * (1 - metallic)
    h = _normalize(l + v)
    NdotL = np.clip(_dot(n, l), 0, 1)
    NdotV = np.clip(_dot(n, v), 0, 1)
    NdotH = np.clip(_dot(n, h), 0, 1)
    VdotH = np.clip(_dot(v, h), 0, 1)
    LdotH = np.clip(_dot(l, h), 0, 1)
    a2 = alpha**2
    D = a2 / (np.pi * (NdotH**2 * (a2 - 1) + 1) ** 2)
    F = spec + (1 - spec) * ((1 - LdotH) ** 5)[..., None]
    if g_model == "cook_torrance":
        G = np.minimum(1, np.minimum(2 * NdotH * NdotV / VdotH, 2 * NdotH * NdotL / VdotH))
    elif g_model == "unity_smith_joint":  # Unity's V = 0.5 / (lambda_v + lambda_l + 1e-5)
        V = 0.5 / (
            NdotL * (NdotV * (1 - alpha) + alpha) + NdotV * (NdotL * (1 - alpha) + alpha) + 1e-5
        )
        G = 4 * NdotL * NdotV * V
    else:

        def lam(c):  # Smith Lambda for GGX; c = 0 gives Lambda = inf, G = 0
            with np.errstate(divide="ignore"):
                return (-1 + np.sqrt(1 + a2 * (1 - c**2) / c**2)) / 2

        G = 1 / (1 + lam(NdotV) + lam(NdotL))
    with np.errstate(divide="ignore", invalid="ignore"):
        fs = D[..., None] * F * G[..., None] / (4 * NdotL * NdotV)[..., None]
    fs = np.where(((NdotL > 0) & (NdotV > 0))[..., None], fs, 0.0)
    if diffuse == "disney":
        fd90 = 0.5 + 2 * LdotH**2 * pr
        fd = (
            diff
            / np.pi
            * ((1 + (fd90 - 1) * (1 - NdotL) ** 5) * (1 + (fd90 - 1) * (1 - NdotV) ** 5))[..., None]
        )
    else:
        fd = diff / np.pi * np.ones_like(NdotL)[..., None]
    return {
        "D": D,
        "F": F,
        "G": G,
        "specular_brdf": fs,
        "diffuse_brdf": fd,
        "NdotL": NdotL,
        "NdotV": NdotV,
        "NdotH": NdotH,
        "VdotH": VdotH,
        "albedo": albedo * np.ones_like(NdotL)[..., None],
        "spec_color": spec * np.ones_like(NdotL)[..., None],
        "alpha": alpha,
    }


def specular_albedo(
    NdotV,
    albedo,
    metallic,
    smoothness,
    g_model="cook_torrance",
    n_theta=800,
    n_phi=400,
    term="specular_brdf",
    diffuse="disney",
):
    """Directional albedo of f_s (or of ``term``): integral of f_s (n.l) over the hemisphere,
    by brute-force midpoint quadrature in (theta_l, phi_l) with n = z (independent of any
    sampling code)."""
    theta = (np.arange(n_theta) + 0.5) / n_theta * (np.pi / 2)
    phi = (np.arange(n_phi) + 0.5) / n_phi * 2 * np.pi
    T, P = np.meshgrid(theta, phi, indexing="ij")
    l = np.stack([np.sin(T) * np.cos(P), np.sin(T) * np.sin(P), np.cos(T)], axis=-1)
    n = np.array([0.0, 0.0, 1.0])
    sv = np.sqrt(max(0.0, 1 - NdotV**2))
    v = np.array([sv, 0.0, NdotV])
    t = terms(
        np.broadcast_to(n, l.shape),
        v,
        l,
        np.broadcast_to(albedo, l.shape),
        np.full(T.shape, metallic),
        np.full(T.shape, smoothness),
        g_model=g_model,
        diffuse=diffuse,
    )
    w = (np.cos(T) * np.sin(T))[..., None] * (np.pi / 2 / n_theta) * (2 * np.pi / n_phi)
    return np.sum(t[term] * w, axis=(0, 1))
