"""The model's derived quantities, written once, with the names and arguments of
osl/ct_brdf.h (docs/model.md "Derived quantities"; Unity's UnityStandardUtils.cginc and
UnityStandardBRDF.cginc):

    pr        = perceptual_roughness(clamp01(smoothness))  = 1 - smoothness
    alpha     = ggx_alpha(pr)                               = max(pr^2, MIN_ALPHA)
    specColor = spec_color_from_metallic(albedo, metallic)  = mix(0.04, albedo, metallic)
    diffColor = diff_color_from_metallic(albedo, metallic)  = albedo 0.96 (1 - metallic)

The bakes (core/ibl_bake.py, core/correction_tables.py), the BRDF plots, the MaterialX network
and the UI read them from here; tests/reference_model.py keeps its own copy on purpose.
"""

MIN_ALPHA = 0.002  # GGX alpha = max(pr^2, MIN_ALPHA): a lobe narrower has no float32 peak
DIELECTRIC_F0 = 0.04  # a dielectric's F0 (Unity's unity_ColorSpaceDielectricSpec)
DIFFUSE_SCALE = 1.0 - DIELECTRIC_F0  # diffColor = albedo * 0.96 * (1 - metallic)


def clamp01(x: float) -> float:
    """Inputs outside their range are clamped, never passed on."""
    return min(1.0, max(0.0, float(x)))


def perceptual_roughness(smoothness: float) -> float:
    """Unity's SmoothnessToPerceptualRoughness: pr = 1 - smoothness (smoothness clamped to
    [0, 1] first, as the shader does)."""
    return 1.0 - clamp01(smoothness)


def ggx_alpha(pr: float) -> float:
    """GGX alpha = max(pr^2, MIN_ALPHA) (Unity's PerceptualRoughnessToRoughness, clamped), of
    the perceptual roughness ``pr``, as ct_brdf.h's ggx_alpha."""
    return max(pr * pr, MIN_ALPHA)


def spec_color_from_metallic(albedo, metallic: float) -> tuple:
    """specColor = mix(0.04, albedo, metallic) per channel (Unity's
    DiffuseAndSpecularFromMetallic)."""
    return tuple(DIELECTRIC_F0 + (a - DIELECTRIC_F0) * metallic for a in albedo)


def diff_color_from_metallic(albedo, metallic: float) -> tuple:
    """diffColor = albedo * 0.96 * (1 - metallic) (Unity's OneMinusReflectivityFromMetallic)."""
    return tuple(a * DIFFUSE_SCALE * (1.0 - metallic) for a in albedo)
