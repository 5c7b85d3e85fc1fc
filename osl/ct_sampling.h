// A part of the Cook-Torrance Lab shader, included by osl/cook_torrance.osl (the add-on
// inlines it when it loads the source: addon/blender/osl_shader.py, source()).
// Sampling the BRDF for the reference integration (docs/model.md "Environment sampling (reference mode)").

#ifndef CT_SAMPLING_H
#define CT_SAMPLING_H

// Sampling the BRDF

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

// Cosine-weighted direction (Malley's method), density (n.l)/pi.
vector sample_cosine(vector n, float u1, float u2)
{
    float r = sqrt(u1);
    float phi = M_2PI * u2;
    vector t, b;
    make_frame(n, t, b);
    return normalize(r * cos(phi) * t + r * sin(phi) * b + sqrt(max(0.0, 1.0 - u1)) * n);
}

// Density of the BRDF sampler in solid angle: the mixture of the GGX lobe
// (D (n.h) / (4 (v.h))) chosen with probability p_spec, and the cosine lobe.
float brdf_pdf(vector n, vector v, vector l, float a, float p_spec)
{
    float NdotL = dot(n, l);
    if (NdotL <= 0.0)
        return 0.0;
    Geometry g = geometry_of(n, v, l);
    float pdf_spec = D_GGX(g.NdotH, a) * g.NdotH / (4.0 * max(g.VdotH, 1e-8));
    return p_spec * pdf_spec + (1.0 - p_spec) * NdotL / M_PI;
}

// ---------------------------------------------------------------------------------------


#endif // CT_SAMPLING_H
