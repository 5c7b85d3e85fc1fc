// A part of the Cook-Torrance Lab shader, included by osl/cook_torrance.osl (the add-on
// inlines it when it loads the source: addon/core/osl_source.py, source()).
// The samplers beside their densities (docs/model.md "Environment sampling (reference
// mode)", "The correction"): the BRDF's (GGX half vectors, the cosine lobe, their mixture),
// GGX's visible normals, and a disk for the lights (ct_lights.h).

#ifndef CT_SAMPLING_H
#define CT_SAMPLING_H

// An orthonormal frame around n (Duff et al. 2017).
void make_frame(vector n, output vector t, output vector b)
{
    float sgn = (n[2] >= 0.0) ? 1.0 : -1.0;
    float a = -1.0 / (sgn + n[2]);
    float bb = n[0] * n[1] * a;
    t = vector(1.0 + sgn * n[0] * n[0] * a, sgn * bb, -sgn * n[0]);
    b = vector(bb, sgn + n[1] * n[1] * a, -n[1]);
}

// GGX half vector with density D(h)(n.h) (Walter et al. 2007, eq. 35-36), via tan^2 for precision.
vector sample_ggx_half(vector n, float a, float u1, float u2)
{
    float tan2 = a * a * u1 / max(1.0 - u1, 1e-12);
    float cos_t = 1.0 / sqrt(1.0 + tan2);
    float sin_t = sqrt(tan2) * cos_t;
    float phi = M_2PI * u2;
    vector t, b;
    make_frame(n, t, b);
    return normalize(sin_t * cos(phi) * t + sin_t * sin(phi) * b + cos_t * n);
}

// The density of sample_ggx_half's direction l = reflect(-v, h) in solid angle:
// D (n.h) / (4 (v.h)) (Walter et al. 2007, eq. 14 and 38), for v.h > 0. The callers guard
// v.h as they always have, so that each computes what it did: brdf_pdf floors it at 1e-8,
// residual_estimate (ct_estimators.h) skips v.h <= 0.
float ggx_half_pdf(float NdotH, float VdotH, float a)
{
    return D_GGX(NdotH, a) * NdotH / (4.0 * VdotH);
}

// Cosine-weighted direction (Malley's method), density (n.l)/pi (brdf_pdf writes it).
vector sample_cosine(vector n, float u1, float u2)
{
    float r = sqrt(u1);
    float phi = M_2PI * u2;
    vector t, b;
    make_frame(n, t, b);
    return normalize(r * cos(phi) * t + r * sin(phi) * b + sqrt(max(0.0, 1.0 - u1)) * n);
}

// A direction from the BRDF sampler: GGX half vectors with probability p_spec, else cosine.
vector sample_brdf(vector n, vector v, float a, float p_spec, float u_pick, float u1, float u2)
{
    if (u_pick < p_spec)
        return reflect(-v, sample_ggx_half(n, a, u1, u2));
    return sample_cosine(n, u1, u2);
}

// Density of the BRDF sampler in solid angle: the mixture of the GGX lobe (ggx_half_pdf)
// chosen with probability p_spec, and the cosine lobe.
float brdf_pdf(vector n, vector v, vector l, float a, float p_spec)
{
    float NdotL = dot(n, l);
    if (NdotL <= 0.0)
        return 0.0;
    Geometry g = geometry_of(n, v, l);
    float pdf_spec = ggx_half_pdf(g.NdotH, max(g.VdotH, 1e-8), a);
    return p_spec * pdf_spec + (1.0 - p_spec) * NdotL / M_PI;
}

// A light direction from GGX's visible normals (Heitz 2018, "Sampling the GGX Distribution
// of Visible Normals", JCGT 7(4), listing 1): h drawn with density G1(v) max(0, v.h) D(h) /
// (n.v) in the stretched frame where the lobe is a hemisphere, then l = reflect(-v, h). Its
// density in l is that over 4 (v.h): G1(v) D(h) / (4 (n.v)) (ggx_visible_pdf). It draws only
// normals the viewer sees (v.h > 0), so at grazing views fewer draws fall below the surface
// than with D (n.h) sampling (at alpha 0.5 and 70 degrees still about 13%), and the weight
// f_s (n.l) / pdf = F G2 / G1 of a Smith lobe stays within [0, 1]; a difference of two G, as
// the scene transport's correction integrates, still grows like 1 / (n.v) there, but no
// faster. For n.v > 0. The scene transport's correction draws with it (ct_correction.h); the
// lab's reference integrator draws with sample_brdf.
vector sample_ggx_visible(vector n, vector v, float a, float u1, float u2)
{
    vector t, b;
    make_frame(n, t, b);
    vector Vh = normalize(vector(a * dot(v, t), a * dot(v, b), dot(v, n)));
    float lensq = Vh[0] * Vh[0] + Vh[1] * Vh[1];
    vector T1 = (lensq > 0.0) ? vector(-Vh[1], Vh[0], 0.0) / sqrt(lensq) : vector(1, 0, 0);
    vector T2 = cross(Vh, T1);
    float r = sqrt(u1), phi = M_2PI * u2;
    float t1 = r * cos(phi), t2 = r * sin(phi);
    float s = 0.5 * (1.0 + Vh[2]);
    t2 = (1.0 - s) * sqrt(max(0.0, 1.0 - t1 * t1)) + s * t2;
    vector Nh = t1 * T1 + t2 * T2 + sqrt(max(0.0, 1.0 - t1 * t1 - t2 * t2)) * Vh;
    vector h = normalize(vector(a * Nh[0], a * Nh[1], max(0.0, Nh[2])));
    return reflect(-v, normalize(h[0] * t + h[1] * b + h[2] * n));
}

// The density of sample_ggx_visible in solid angle: G1(v) D(h) / (4 (n.v)), 0 below the
// surface.
float ggx_visible_pdf(vector n, vector v, vector l, float a)
{
    if (dot(n, l) <= 0.0)
        return 0.0;
    Geometry g = geometry_of(n, v, l);
    if (g.NdotV <= 0.0 || g.VdotH <= 0.0)
        return 0.0;
    return G1_SmithGGX(g.NdotV, a) * D_GGX(g.NdotH, a) / (4.0 * g.NdotV);
}

// Shirley and Chiu's concentric map of the unit square onto the unit disk.
void concentric_disk(float u1, float u2, output float x, output float y)
{
    float a = 2.0 * u1 - 1.0, b = 2.0 * u2 - 1.0;
    x = 0.0; y = 0.0;
    if (a == 0.0 && b == 0.0)
        return;
    float r, phi;
    if (abs(a) > abs(b)) { r = a; phi = M_PI_4 * b / a; }
    else { r = b; phi = M_PI_2 - M_PI_4 * a / b; }
    x = r * cos(phi);
    y = r * sin(phi);
}

#endif // CT_SAMPLING_H
