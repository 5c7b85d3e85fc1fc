// A part of the Cook-Torrance Lab shader, included by osl/cook_torrance.osl (the add-on
// inlines it when it loads the source: addon/core/osl_source.py, source()).
// The model's BRDF: derived quantities, the terms D, F, G, f_d and f_s (docs/model.md
// "Derived quantities", "The terms").

#ifndef CT_BRDF_H
#define CT_BRDF_H

// ---------------------------------------------------------------------------------------
// Derived quantities (docs/model.md "Derived quantities"; Unity's UnityStandardUtils.cginc)

float perceptual_roughness(float smoothness) { return 1.0 - smoothness; }

float ggx_alpha(float pr) { return max(pr * pr, 0.002); }

color spec_color_from_metallic(color albedo, float metallic)
{
    return mix(color(0.04), albedo, metallic);
}

color diff_color_from_metallic(color albedo, float metallic)
{
    return albedo * 0.96 * (1.0 - metallic);
}

float pow5(float x) { return (x * x) * (x * x) * x; }

float max_component(color c) { return max(c[0], max(c[1], c[2])); }

// ---------------------------------------------------------------------------------------
// The terms (docs/model.md "The terms")

// D: GGX normal distribution.  D = a^2 / (pi ((n.h)^2 (a^2 - 1) + 1)^2)
float D_GGX(float NdotH, float a)
{
    float a2 = a * a;
    float d = NdotH * NdotH * (a2 - 1.0) + 1.0;
    return a2 / (M_PI * d * d);
}

// F: Schlick's approximation on Unity's specular colour.  F = F0 + (1 - F0)(1 - l.h)^5
color F_Schlick(color F0, float LdotH)
{
    return F0 + (color(1.0) - F0) * pow5(1.0 - LdotH);
}

// G: Cook-Torrance geometric attenuation.  G = min(1, 2(n.h)(n.v)/(v.h), 2(n.h)(n.l)/(v.h))
float G_CookTorrance(float NdotH, float NdotV, float NdotL, float VdotH)
{
    float vh = max(VdotH, 1e-8);
    return min(1.0, min(2.0 * NdotH * NdotV / vh, 2.0 * NdotH * NdotL / vh));
}

// G: height-correlated Smith for GGX.  G = 1 / (1 + Lambda(v) + Lambda(l))
//    = 2 (n.l)(n.v) / ((n.l) sqrt((n.v)^2 (1 - a^2) + a^2) + (n.v) sqrt((n.l)^2 (1 - a^2) + a^2))
float G_SmithGGXCorrelated(float NdotV, float NdotL, float a)
{
    float a2 = a * a;
    float lv = NdotL * sqrt(NdotV * NdotV * (1.0 - a2) + a2);
    float ll = NdotV * sqrt(NdotL * NdotL * (1.0 - a2) + a2);
    return 2.0 * NdotL * NdotV / max(lv + ll, 1e-20);
}

// Smith's masking for GGX toward v: G1 = 2 (n.v) / ((n.v) + sqrt(a^2 + (1 - a^2)(n.v)^2))
// (Walter et al. 2007, eq. 34).
float G1_SmithGGX(float NdotV, float a)
{
    float a2 = a * a;
    return 2.0 * NdotV / max(NdotV + sqrt(a2 + (1.0 - a2) * NdotV * NdotV), 1e-20);
}

// G: Unity's approximate height-correlated Smith visibility (SmithJointGGXVisibilityTerm,
// UnityStandardBRDF.cginc): lambda_v = n.l (n.v (1 - a) + a), lambda_l = n.v (n.l (1 - a) + a),
// V = 0.5 / (lambda_v + lambda_l + 1e-5), so that f_s = D F V; as a G, 4 (n.l)(n.v) V.
float G_UnitySmithJoint(float NdotV, float NdotL, float a)
{
    float lambda_v = NdotL * (NdotV * (1.0 - a) + a);
    float lambda_l = NdotV * (NdotL * (1.0 - a) + a);
    return 4.0 * NdotL * NdotV * 0.5 / (lambda_v + lambda_l + 1e-5);
}

float G_term(string g_model, float NdotH, float NdotV, float NdotL, float VdotH, float a)
{
    if (g_model == "smith_ggx_correlated")
        return G_SmithGGXCorrelated(NdotV, NdotL, a);
    if (g_model == "unity_smith_joint")
        return G_UnitySmithJoint(NdotV, NdotL, a);
    return G_CookTorrance(NdotH, NdotV, NdotL, VdotH);
}

// Specular BRDF.  f_s = D F G / (4 (n.l)(n.v)), and 0 where n.l <= 0 or n.v <= 0.
color specular_brdf(float D, color F, float G, float NdotL, float NdotV)
{
    if (NdotL <= 0.0 || NdotV <= 0.0)
        return color(0.0);
    return D * F * G / (4.0 * max(NdotL * NdotV, 1e-12));
}

// Diffuse BRDF.  Disney:  fd90 = 0.5 + 2 (l.h)^2 pr,
//   f_d = diffColor / pi (1 + (fd90 - 1)(1 - n.l)^5)(1 + (fd90 - 1)(1 - n.v)^5);   Lambert: diffColor / pi.
color diffuse_brdf(string diffuse_model, color diffColor, float NdotL, float NdotV, float LdotH,
                   float pr)
{
    if (diffuse_model == "lambert")
        return diffColor / M_PI;
    float fd90 = 0.5 + 2.0 * LdotH * LdotH * pr;
    float light_scatter = 1.0 + (fd90 - 1.0) * pow5(1.0 - NdotL);
    float view_scatter = 1.0 + (fd90 - 1.0) * pow5(1.0 - NdotV);
    return diffColor / M_PI * light_scatter * view_scatter;
}

// The clamped dot products of one (n, v, l) configuration, and the BRDF there.
struct Geometry {
    float NdotL; float NdotV; float NdotH; float VdotH; float LdotH;
};

Geometry geometry_of(vector n, vector v, vector l)
{
    vector h = l + v;
    float hl = length(h);
    h = (hl > 1e-12) ? h / hl : n;
    Geometry g;
    g.NdotL = clamp(dot(n, l), 0.0, 1.0);
    g.NdotV = clamp(dot(n, v), 0.0, 1.0);
    g.NdotH = clamp(dot(n, h), 0.0, 1.0);
    g.VdotH = clamp(dot(v, h), 0.0, 1.0);
    g.LdotH = clamp(dot(l, h), 0.0, 1.0);
    return g;
}


#endif // CT_BRDF_H
