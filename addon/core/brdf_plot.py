"""The BRDF plotted, as Disney's BRDF Explorer shows one (docs/model.md "BRDF plots"): the
θh × θd image slice in Rusinkiewicz's coordinates (Burley 2012, section 3), polar lobes in the
incidence plane, and the directional albedo against the view angle.

This module makes the *configurations* (n, v, l) at which the model is evaluated and turns the
values back into plots; the values themselves come from the model's own code, a render in which
each pixel evaluates one configuration (blender/model_eval.py), never from a re-implementation.
The shader reads v from the camera (toward the viewer, +Z there), so each configuration is
turned rigidly until v = +Z (``view_frame``): the BRDF depends only on the angles between n,
v and l, which a rotation keeps.

Conventions (n = +Z in the canonical frame):
- slice: column i at θh = (i + 0.5)°, row j (top row j = 0) at θd = (j + 0.5)°, φd = 90°;
  h = (sin θh, 0, cos θh), d = (sin θd cos φd, sin θd sin φd, cos θd), l = R_y(θh) d and
  v = R_y(θh) (-d_x, -d_y, d_z); f_r = 0 where n.l <= 0 or n.v <= 0.
- lobe: v = (sin θv, 0, cos θv), l = (sin θl, 0, cos θl) for θl from -90° to 90° (the mirror
  direction is at θl = -θv); the curve is f_r (n.l).
- albedo: ∫ f (n.l) dl over the hemisphere at θv = (k + 0.5) 2°: the specular part by the
  DFG table's quadrature of GGX half vectors (ibl_bake.ggx_half_vectors; the weight
  4 (v.h) / (D (n.h))), the diffuse part on a midpoint grid mapped through the cosine
  distribution (the weight π / (n.l)). As the reference integrator does, the specular weight
  takes D from the model itself (its D view at the same configuration): near a mirror's peak
  (α = 0.002) the shader's float32 n.h resolves D only to a few per cent, and this way that
  rounding cancels (the plot's D slice shows D itself).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .errors import UserError
from .model import (
    DEFAULT_ALBEDO,
    DIFFUSE_MODELS,
    ENERGY_MODES,
    G_MODELS,
    IMPLEMENTATIONS,
    REC709_LUMINANCE,
    UNITS,
    ModelOptions,
    ggx_alpha,
    perceptual_roughness,
)

SLICE_SIZE = 90  # 1° steps of θh and θd
SLICE_PHI_D = 90.0  # degrees
LOBE_VIEW_ANGLES = (0.0, 30.0, 60.0, 75.0)
LOBE_STEPS = 361  # θl from -90° to 90° in 0.5° steps
ALBEDO_ANGLES = 45  # θv = 1°, 3°, ..., 89°
ALBEDO_GRID = (128, 64)  # the specular quadrature's (theta_h, phi) grid
PACK_WIDTH = 512  # the render's width: every configuration one pixel

# What a slice can show: the BRDF ("f_r", the sum of the model's specular_brdf and
# diffuse_brdf views) and the model's term views that depend on the configuration.
BRDF_VIEWS = ("specular_brdf", "diffuse_brdf")
WEIGHT_VIEW = "D"  # the specular albedo's weight reads the model's own D
SLICE_VIEWS = ("D", "F", "G", "specular_brdf", "diffuse_brdf", "NdotL", "NdotV", "NdotH", "VdotH")
# --compare: the switch each key changes, and its values
COMPARE_KEYS = {
    "g": ("g_model", G_MODELS),
    "diffuse": ("diffuse_model", DIFFUSE_MODELS),
    "energy": ("energy", ENERGY_MODES),
}
PLOT_SHADERS = IMPLEMENTATIONS  # the model's own code: either implementation

# What each slice shows, for its title, and whether a log scale suits it.
VIEW_TITLES = {
    "f_r": ("f_r = f_d + f_s (sr⁻¹)", True),
    "D": ("D (sr⁻¹)", True),
    "F": ("F (Schlick)", False),
    "G": ("G", False),
    "specular_brdf": ("f_s (sr⁻¹)", True),
    "diffuse_brdf": ("f_d (sr⁻¹)", True),
    "NdotL": ("n.l", False),
    "NdotV": ("n.v", False),
    "NdotH": ("n.h", False),
    "VdotH": ("v.h", False),
}


def luminance(rgb: np.ndarray) -> np.ndarray:
    return np.asarray(rgb, dtype=np.float64)[..., :3] @ np.array(REC709_LUMINANCE)


def slice_name(view: str = "f_r", tag: str = "") -> str:
    """slice (f_r), slice_<view>, slice_<tag> (a variant's f_r)."""
    return "slice" + (f"_{view}" if view != "f_r" else "") + (f"_{tag}" if tag else "")


# ----------------------------------------------------------------------------------------
# Configurations


def _rot_y(x: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """R_y(θ) x: x' = x cos θ + z sin θ, z' = -x sin θ + z cos θ."""
    c, s = np.cos(theta), np.sin(theta)
    return np.stack(
        [x[..., 0] * c + x[..., 2] * s, x[..., 1], -x[..., 0] * s + x[..., 2] * c], axis=-1
    )


def rusinkiewicz(theta_h, theta_d, phi_d):
    """(l, v) for half-vector angles (radians, broadcast together), with n = +Z."""
    theta_h, theta_d, phi_d = np.broadcast_arrays(
        *(np.asarray(a, dtype=np.float64) for a in (theta_h, theta_d, phi_d))
    )
    d = np.stack(
        [np.sin(theta_d) * np.cos(phi_d), np.sin(theta_d) * np.sin(phi_d), np.cos(theta_d)], axis=-1
    )
    mirrored = d * np.array([-1.0, -1.0, 1.0])
    return _rot_y(d, theta_h), _rot_y(mirrored, theta_h)


def slice_angles(size: int = SLICE_SIZE):
    """The slice's pixel-centre angles in degrees: (θh by column, θd by row)."""
    centres = (np.arange(size) + 0.5) * 90.0 / size
    return centres, centres


def slice_geometry(size: int = SLICE_SIZE, phi_d_deg: float = SLICE_PHI_D):
    """(l, v), each (size, size, 3): row j at θd_j, column i at θh_i."""
    th, td = slice_angles(size)
    TD, TH = np.meshgrid(np.radians(td), np.radians(th), indexing="ij")
    return rusinkiewicz(TH, TD, math.radians(phi_d_deg))


def lobe_angles(steps: int = LOBE_STEPS) -> np.ndarray:
    return np.linspace(-90.0, 90.0, steps)


def lobe_geometry(view_angles=LOBE_VIEW_ANGLES, steps: int = LOBE_STEPS):
    """(l, v), each (len(view_angles), steps, 3), in the incidence plane (XZ)."""
    tv = np.radians(np.asarray(view_angles, dtype=np.float64))[:, None]
    tl = np.radians(lobe_angles(steps))[None, :]
    tv, tl = np.broadcast_arrays(tv, tl)
    zeros = np.zeros_like(tv)
    return (
        np.stack([np.sin(tl), zeros, np.cos(tl)], axis=-1),
        np.stack([np.sin(tv), zeros, np.cos(tv)], axis=-1),
    )


def albedo_angles(count: int = ALBEDO_ANGLES) -> np.ndarray:
    """θv in degrees: the centres of ``count`` equal steps of [0°, 90°]."""
    return (np.arange(count) + 0.5) * 90.0 / count


def _grid(nu: int, nphi: int):
    u1 = (np.arange(nu) + 0.5) / nu
    u2 = (np.arange(nphi) + 0.5) / nphi
    return np.meshgrid(u1, u2, indexing="ij")


def _views(theta_v_deg) -> np.ndarray:
    tv = np.radians(np.asarray(theta_v_deg, dtype=np.float64))
    return np.stack([np.sin(tv), np.zeros_like(tv), np.cos(tv)], axis=-1)


def specular_quadrature(theta_v_deg, alpha: float, grid=ALBEDO_GRID):
    """(l, v, weight), each (len(θv), nu * nphi[, 3]): ∫ f (n.l) dl ≈ Σ f(l) (n.l) weight / D,
    with D the GGX D at l's half vector. The half vectors are the DFG table's quadrature
    (ibl_bake.ggx_half_vectors: GGX-distributed, only those whose l is above the horizon, on
    one side of the plane of n and v, the BRDF being symmetric about it), of density D (n.h)
    in h and D (n.h) / (4 (v.h)) in l: weight = 4 (v.h) / (n.h) times the quadrature's."""
    from .ibl_bake import ggx_half_vectors

    tv = np.radians(np.asarray(theta_v_deg, dtype=np.float64))
    q = ggx_half_vectors(np.cos(tv), alpha, *grid)
    shape = q["phi"].shape
    nh, sh, phi, vh, sv, w = (
        np.broadcast_to(q[k], shape) for k in ("nh", "sh", "phi", "vh", "sv", "weight")
    )
    h = np.stack([sh * np.cos(phi), sh * np.sin(phi), nh], axis=-1)
    v = np.stack([sv, np.zeros(shape), np.broadcast_to(np.cos(tv)[:, None, None], shape)], axis=-1)
    l = 2.0 * vh[..., None] * h - v
    weight = 4.0 * vh / nh * w
    n = len(tv)
    return l.reshape(n, -1, 3), v.reshape(n, -1, 3), weight.reshape(n, -1)


def diffuse_quadrature(theta_v_deg, grid=(32, 64)):
    """(l, v, weight), each (len(θv), nu * nphi[, 3]): ∫ f (n.l) dl ≈ Σ f(l) (n.l) weight,
    l cosine-distributed (Malley's method) on a midpoint grid."""
    u1, u2 = (a.ravel() for a in _grid(*grid))
    r, phi = np.sqrt(u1), 2.0 * np.pi * u2
    l1 = np.stack([r * np.cos(phi), r * np.sin(phi), np.sqrt(1.0 - u1)], axis=-1)
    n = len(theta_v_deg)
    l = np.broadcast_to(l1[None], (n, len(u1), 3))
    v = np.broadcast_to(_views(theta_v_deg)[:, None, :], l.shape)
    weight = np.broadcast_to(np.pi / (l1[:, 2] * len(u1)), (n, len(u1)))
    return np.ascontiguousarray(l), np.ascontiguousarray(v), np.ascontiguousarray(weight)


def view_frame(v: np.ndarray, l: np.ndarray, n=(0.0, 0.0, 1.0)):
    """(n', l'): n and l turned by the rotation that takes v to +Z, the shader's view
    direction (R = I + [w]x + [w]x^2 / (1 + c), w = v x z, c = v.z; v.z > -1)."""
    v = np.asarray(v, dtype=np.float64)
    n = np.broadcast_to(np.asarray(n, dtype=np.float64), v.shape)
    w = np.stack([v[..., 1], -v[..., 0], np.zeros(v.shape[:-1])], axis=-1)  # v x (0, 0, 1)
    c = v[..., 2:3]

    def turn(x):
        wx = np.cross(w, x)
        return x + wx + np.cross(w, wx) / (1.0 + c)

    return turn(n), turn(np.asarray(l, dtype=np.float64))


# ----------------------------------------------------------------------------------------
# The settings


def parse_compare(items) -> tuple:
    """``--compare`` items ("g=smith_ggx_correlated", comma lists allowed) as ((key, value),
    ...), in order, without repeats."""
    out = []
    for item in items or ():
        for word in str(item).split(","):
            word = word.strip()
            if not word:
                continue
            key, sep, value = word.partition("=")
            key, value = key.strip(), value.strip()
            if not sep or key not in COMPARE_KEYS:
                raise UserError(
                    f"malformed --compare {word!r}; give KEY=VALUE with KEY one of "
                    f"{', '.join(COMPARE_KEYS)} (e.g. g=smith_ggx_correlated)"
                )
            values = COMPARE_KEYS[key][1]
            if value not in values:
                raise UserError(
                    f"unknown {key} {value!r} in --compare; choose one of: {', '.join(values)}"
                )
            if (key, value) not in out:
                out.append((key, value))
    return tuple(out)


def _unit_number(x, what: str) -> float:
    try:
        x = float(x)
    except (TypeError, ValueError):
        raise UserError(f"malformed {what} {x!r}; give a number from 0 to 1") from None
    if not (math.isfinite(x) and 0.0 <= x <= 1.0):
        raise UserError(f"{what} {x!r} out of range; use 0 to 1")
    return x


@dataclass(frozen=True)
class PlotSettings:
    """What one BRDF plot shows: the surface's values, the model's switches, which
    implementation evaluates it, extra term views to slice, and the variants to overlay
    (switches changed from these, one at a time)."""

    metallic: float = 0.0
    smoothness: float = 0.5
    albedo: tuple = DEFAULT_ALBEDO
    g_model: str = G_MODELS[0]
    diffuse_model: str = DIFFUSE_MODELS[0]
    units: str = UNITS[0]
    energy: str = ENERGY_MODES[0]
    shader: str = "osl"
    views: tuple = ()
    compare: tuple = field(default=())

    def __post_init__(self):
        object.__setattr__(self, "metallic", _unit_number(self.metallic, "metallic"))
        object.__setattr__(self, "smoothness", _unit_number(self.smoothness, "smoothness"))
        albedo = tuple(self.albedo)
        if len(albedo) != 3:
            raise UserError(f"malformed albedo {self.albedo!r}; give R,G,B")
        object.__setattr__(self, "albedo", tuple(_unit_number(a, "albedo") for a in albedo))
        if self.shader not in PLOT_SHADERS:
            raise UserError(
                f"unknown shader {self.shader!r} for a plot; choose one of: "
                f"{', '.join(PLOT_SHADERS)}"
            )
        for v in self.views:
            if v not in SLICE_VIEWS:
                raise UserError(
                    f"view {v!r} cannot be sliced; choose from: {', '.join(SLICE_VIEWS)}"
                )
        object.__setattr__(self, "views", tuple(dict.fromkeys(self.views)))
        object.__setattr__(self, "compare", parse_compare([f"{k}={v}" for k, v in self.compare]))
        self.options()  # the switches, validated

    def options(self, view: str = "specular_brdf", **changes) -> ModelOptions:
        # the indirect light does not enter a term view; split_sum is both implementations'
        values = dict(
            g_model=self.g_model,
            diffuse_model=self.diffuse_model,
            units=self.units,
            energy=self.energy,
            ibl="split_sum",
        )
        values.update(changes)
        return ModelOptions(view=view, **values)

    @property
    def alpha(self) -> float:
        return ggx_alpha(perceptual_roughness(self.smoothness))

    def variants(self) -> list:
        """[(tag, label, switch changes)]: the plot's own model first (tag "", labelled with
        its switches), then each --compare item that changes something (labelled with what
        it changes)."""
        out = [("", self.label(), {})]
        for key, value in self.compare:
            switch = COMPARE_KEYS[key][0]
            if getattr(self, switch) != value:
                out.append((f"{key}-{value}", _switch_label(switch, value), {switch: value}))
        return out

    def label(self) -> str:
        """Its G and diffuse, and "energy compensated" when it is."""
        keys = ("g_model", "diffuse_model") + (("energy",) if self.energy != "none" else ())
        return ", ".join(_switch_label(k, getattr(self, k)) for k in keys)

    def describe(self) -> dict:
        return {
            "metallic": self.metallic,
            "smoothness": self.smoothness,
            "perceptual_roughness": 1.0 - self.smoothness,
            "alpha": self.alpha,
            "albedo": list(self.albedo),
            "g_model": self.g_model,
            "diffuse_model": self.diffuse_model,
            "units": self.units,
            "energy": self.energy,
            "shader": self.shader,
            "views": list(self.views),
            "compare": [f"{k}={v}" for k, v in self.compare],
        }


def _switch_label(switch: str, value: str) -> str:
    return {
        "g_model": f"G {value}",
        "diffuse_model": f"{value} diffuse",
        "energy": "energy compensated" if value == "compensated" else "single scattering",
    }[switch]


# ----------------------------------------------------------------------------------------
# Packing configurations into one render, and the values back out


@dataclass
class Layout:
    """Every configuration of a plot as one pixel of a PACK_WIDTH-wide render: named sets
    of shapes ``shapes[name]`` laid out one after another."""

    shapes: dict
    n: np.ndarray = None  # (H, W, 3): the normal in the view frame
    l: np.ndarray = None  # (H, W, 3): the direction toward the light, likewise
    weights: dict = field(default_factory=dict)  # the quadratures' weights
    cos_l: dict = field(default_factory=dict)  # n.l of each set's configurations
    cos_v: dict = field(default_factory=dict)  # and n.v

    @property
    def count(self) -> int:
        return sum(int(np.prod(s)) for s in self.shapes.values())

    @property
    def size(self) -> tuple:
        return PACK_WIDTH, -(-self.count // PACK_WIDTH)

    def unpack(self, image: np.ndarray) -> dict:
        """{set name: values of shape shapes[name] + (channels,)} from a rendered image."""
        flat = image.reshape(-1, image.shape[-1])
        out, start = {}, 0
        for name, shape in self.shapes.items():
            k = int(np.prod(shape))
            out[name] = flat[start : start + k].reshape(tuple(shape) + (image.shape[-1],))
            start += k
        return out


def layout(settings: PlotSettings) -> Layout:
    """The slice, the lobes and the two albedo quadratures, in one layout."""
    sets = {"slice": slice_geometry(), "lobe": lobe_geometry()}
    tv = albedo_angles()
    l, v, w_s = specular_quadrature(tv, settings.alpha)
    sets["albedo_specular"] = (l, v)
    l, v, w_d = diffuse_quadrature(tv)
    sets["albedo_diffuse"] = (l, v)
    shapes = {name: lv[0].shape[:-1] for name, lv in sets.items()}
    out = Layout(
        shapes,
        weights={"albedo_specular": w_s, "albedo_diffuse": w_d},
        cos_l={name: lv[0][..., 2] for name, lv in sets.items()},
        cos_v={name: lv[1][..., 2] for name, lv in sets.items()},
    )
    w, h = out.size
    n_img = np.zeros((h * w, 3))
    l_img = np.zeros((h * w, 3))
    n_img[:, 2] = 1.0  # padding: n = v = l
    l_img[:, 2] = 1.0
    start = 0
    for l, v in sets.values():
        n1, l1 = view_frame(v.reshape(-1, 3), l.reshape(-1, 3))
        n_img[start : start + len(n1)] = n1
        l_img[start : start + len(l1)] = l1
        start += len(n1)
    out.n, out.l = n_img.reshape(h, w, 3), l_img.reshape(h, w, 3)
    return out


def assemble(lay: Layout, values: dict, views=(), d_view=None) -> dict:
    """One variant's results from its renders ({view: image}, BRDF_VIEWS at least; the D
    view in ``values`` or as ``d_view``, D being the same in every variant): the slice of f_r
    and of each of ``views``, the lobes f_r (n.l) and the directional albedos (specular,
    diffuse, total; each (len(θv), 3))."""
    parts = {view: lay.unpack(img) for view, img in values.items()}
    d = lay.unpack(values.get(WEIGHT_VIEW, d_view))["albedo_specular"][..., 0]
    f_r = {name: parts["specular_brdf"][name] + parts["diffuse_brdf"][name] for name in lay.shapes}
    valid = ((lay.cos_l["slice"] > 0) & (lay.cos_v["slice"] > 0))[..., None]
    out = {"slice": {"f_r": np.where(valid, f_r["slice"], 0.0).astype(np.float32)}}
    for view in views:
        out["slice"][view] = parts[view]["slice"].astype(np.float32)
    out["lobe"] = f_r["lobe"].astype(np.float64) * np.maximum(lay.cos_l["lobe"], 0.0)[..., None]
    spec = _integrate(
        parts["specular_brdf"]["albedo_specular"]
        / np.maximum(d, 1e-30)[..., None].astype(np.float64),
        lay,
        "albedo_specular",
    )
    diff = _integrate(parts["diffuse_brdf"]["albedo_diffuse"], lay, "albedo_diffuse")
    out["albedo"] = {"specular": spec, "diffuse": diff, "total": spec + diff}
    return out


def _integrate(values: np.ndarray, lay: Layout, name: str) -> np.ndarray:
    """Σ f (n.l) weight over each θv's quadrature points; (len(θv), 3)."""
    w = np.maximum(lay.cos_l[name], 0.0) * lay.weights[name]
    terms = np.where((w > 0)[..., None], values.astype(np.float64) * w[..., None], 0.0)
    return np.sum(terms, axis=1)
