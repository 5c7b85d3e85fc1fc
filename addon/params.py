"""The model's parameters, options and views: the one place that names them.

Everything here follows shared/SPEC.md (Cook-Torrance Lab model specification):
inputs, the optional model switches, units, IBL modes and the views used for
term isolation. The OSL shader, the materials, the command line and the tests
all read these names from here.
"""

from __future__ import annotations

import math

# --- Inputs (SPEC "Inputs"): name -> (min, max, default)
INPUT_RANGES = {
    "metallic": (0.0, 1.0, 0.0),
    "smoothness": (0.0, 1.0, 0.5),
}
DEFAULT_ALBEDO = (0.8, 0.8, 0.8)
MATRIX_ALBEDO = (1.0, 0.766, 0.336)    # gold: metals show their colour in the matrix

# --- Model switches (SPEC "Optional model switches"); the first is the default.
G_MODELS = ("cook_torrance", "smith_ggx_correlated")
DIFFUSE_MODELS = ("disney", "lambert")
UNITS = ("physical", "unity")
# reference: Monte Carlo against the HDRI; split_sum (Karis 2013) and unity (Unity's
# reflection-probe approximation) use the files baked by ibl_bake.
IBL_MODES = ("reference", "split_sum", "unity")
BAKED_IBL_MODES = ("split_sum", "unity")
IBL_LABELS = {"reference": ("Reference", "Monte Carlo integration against the HDRI"),
              "split_sum": ("Split-Sum", "Pre-filtered levels and the DFG table (baked, cached)"),
              "unity": ("Unity", "Unity's reflection-probe approximation (baked, cached)")}

# --- Views (SPEC "Views"): every implementation offers exactly these.
LIGHTING_VIEWS = ("full", "direct", "indirect", "direct_diffuse", "direct_specular",
                  "indirect_diffuse", "indirect_specular")
TERM_VIEWS = ("D", "F", "G", "specular_brdf", "diffuse_brdf",
              "NdotL", "NdotV", "NdotH", "VdotH", "normal", "albedo", "spec_color")
VIEWS = LIGHTING_VIEWS + TERM_VIEWS

# Views that are rendered at pixel centres with no jitter (one exact shading point a pixel).
EXACT_VIEWS = TERM_VIEWS

# Views whose PNG uses Blender's AgX view transform; the rest use Standard (raw values).
AGX_VIEWS = ("full", "direct", "indirect", "direct_diffuse", "direct_specular",
             "indirect_diffuse", "indirect_specular")

REC709_LUMINANCE = (0.2126, 0.7152, 0.0722)     # Y of linear Rec. 709 RGB

# --- Derived quantities (SPEC "Derived quantities"; Unity's UnityStandardUtils/BRDF)
DIELECTRIC_F0 = 0.04
MIN_ALPHA = 0.002


def clamp01(x: float) -> float:
    """SPEC: values outside the range are clamped, never propagated."""
    return min(1.0, max(0.0, float(x)))


def perceptual_roughness(smoothness: float) -> float:
    """Unity's SmoothnessToPerceptualRoughness: pr = 1 - smoothness."""
    return 1.0 - clamp01(smoothness)


def ggx_alpha(smoothness: float) -> float:
    """GGX alpha = max(pr^2, 0.002) (Unity's PerceptualRoughnessToRoughness, clamped)."""
    return max(perceptual_roughness(smoothness) ** 2, MIN_ALPHA)


def spec_color(albedo, metallic: float):
    """Unity's DiffuseAndSpecularFromMetallic: specColor = lerp(0.04, albedo, metallic)."""
    m = clamp01(metallic)
    return tuple(DIELECTRIC_F0 * (1 - m) + clamp01(a) * m for a in albedo)


def diff_color(albedo, metallic: float):
    """diffColor = albedo * 0.96 * (1 - metallic) (Unity's oneMinusReflectivity)."""
    m = clamp01(metallic)
    return tuple(clamp01(a) * (1 - DIELECTRIC_F0) * (1 - m) for a in albedo)


def units_factor(units: str) -> float:
    """SPEC "Units": Unity output = pi x physical output for direct light."""
    return math.pi if units == "unity" else 1.0


def matrix_values(rows: int, cols: int):
    """Sphere-matrix parameters (SPEC "The sphere matrix").

    Columns: metallic 0 -> 1 left to right. Rows: smoothness 1 -> 0 top to bottom.
    Yields (row, col, metallic, smoothness).
    """
    for r in range(rows):
        smooth = 1.0 - r / (rows - 1) if rows > 1 else 0.5
        for c in range(cols):
            metal = c / (cols - 1) if cols > 1 else 0.5
            yield r, c, metal, smooth


class ModelOptions:
    """The shader's settings other than the surface inputs (SPEC switches, view, IBL)."""

    def __init__(self, view="full", g_model=G_MODELS[0], diffuse_model=DIFFUSE_MODELS[0],
                 units=UNITS[0], ibl=IBL_MODES[0], env_samples=4, env_visibility=False,
                 sun_shadow=True, seed=0):
        self.view = view
        self.g_model = g_model
        self.diffuse_model = diffuse_model
        self.units = units
        self.ibl = ibl
        self.env_samples = int(env_samples)
        self.env_visibility = bool(env_visibility)
        self.sun_shadow = bool(sun_shadow)
        self.seed = int(seed)
        self.validate()

    def validate(self):
        from .errors import UserError
        for value, allowed, what in ((self.view, VIEWS, "view"), (self.g_model, G_MODELS, "G"),
                                     (self.diffuse_model, DIFFUSE_MODELS, "diffuse"),
                                     (self.units, UNITS, "units"), (self.ibl, IBL_MODES, "IBL")):
            if value not in allowed:
                raise UserError(f"unknown {what} {value!r}; choose one of: {', '.join(allowed)}")
        if not 1 <= self.env_samples <= 1024:
            raise UserError(f"env samples {self.env_samples} out of range; use 1 to 1024")

    def as_dict(self):
        return dict(vars(self))
