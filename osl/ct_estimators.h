// A part of the Cook-Torrance Lab shader, included by osl/cook_torrance.osl (the add-on
// inlines it when it loads the source: addon/core/osl_source.py, source()).
// The shader's estimators, one function each, in the order of docs/model.md: the term
// views ("Views (term isolation)"), the key Sun and the light slots ("Lighting": Direct;
// "Lights"), the baked modes ("Lighting": split_sum, unity), the reference integration of the
// world ("Lighting": reference; "Environment sampling (reference mode)"), the scene
// transport's correction and its residual albedo ("The correction (a control variate)").
// Each adds to `result` in the order the shader always has, so a render is the same to the
// last bit.

#ifndef CT_ESTIMATORS_H
#define CT_ESTIMATORS_H

// Which parts of the light a view shows (docs/model.md "Views (term isolation)").
struct Want {
    int direct; int indirect; int diffuse; int specular;
};

Want wants_of(string view)
{
    Want w;
    w.direct = (view == "full" || view == "direct" || view == "direct_diffuse" ||
                view == "direct_specular");
    w.indirect = (view == "full" || view == "indirect" || view == "indirect_diffuse" ||
                  view == "indirect_specular");
    w.diffuse = (view != "direct_specular" && view != "indirect_specular");
    w.specular = (view != "direct_diffuse" && view != "indirect_diffuse");
    return w;
}

// A term view (the key light's direction, no lighting factor; docs/model.md "Views (term
// isolation)", the terms as "The terms" and "Units" define them): 1 and its value in `out`,
// else 0.
int term_view(string view, Geometry g, float D, color F, float G, color f_s, color f_d,
              float k_units, vector n, color base, color specColor, output color out)
{
    if (view == "D") out = color(D);
    else if (view == "F") out = F;
    else if (view == "G") out = color(G);
    else if (view == "specular_brdf") out = k_units * f_s;
    else if (view == "diffuse_brdf") out = k_units * f_d;
    else if (view == "NdotL") out = color(g.NdotL);
    else if (view == "NdotV") out = color(g.NdotV);
    else if (view == "NdotH") out = color(g.NdotH);
    else if (view == "VdotH") out = color(g.VdotH);
    else if (view == "normal") out = color(n[0], n[1], n[2]);
    else if (view == "albedo") out = base;
    else if (view == "spec_color") out = specColor;
    else return 0;
    return 1;
}

// The key Sun: L = f_r E (n.l) (docs/model.md "Units", "Lighting": Direct), shadowed by a
// shadow ray ("Shadows"; nothing without a key Sun: E = 0).
// f_d, f_s: the model toward it; in the scene transport the correction's (brdf_toward).
void sun_light(Surface sf, point P, Geometry g, vector l, color E, int shadow, int rays,
               color f_d, color f_s, Want w, float k_units, output color result)
{
    if (!(g.NdotL > 0.0 && max_component(E) > 0.0))
        return;
    float visible = 1.0;
    if (shadow && shadowed(P, l, FAR_AWAY, rays))
        visible = 0.0;
    color sun_d = f_d, sun_s = f_s;
    if (sf.closures)
        brdf_toward(sf, l, sun_d, sun_s);
    color f = color(0);
    if (w.diffuse) f += sun_d;
    if (w.specular) f += sun_s;
    result += k_units * f * E * g.NdotL * visible;
}

// The light slots (docs/model.md "Lights"; ct_lights.h shade_light: one light sample and one
// BRDF sample each, balance heuristic, Veach 1995);
// f_s is 0 where n.v <= 0, f_d is not (as for the key Sun, and in the node group).
void slot_lights(Light lights[8], point P, Surface sf, float p_spec, int rays, point key,
                 Want w, float k_units, output color result)
{
    for (int i = 0; i < 8; i++) {
        if (!shines(lights[i]))
            continue;
        float u[5];
        for (int k = 0; k < 5; k++)
            u[k] = uniform01(key, STREAM_LIGHTS + 8 * i + k);
        color light_d, light_s;
        shade_light(lights[i], P, sf, p_spec, rays, u, light_d, light_s);
        if (w.diffuse) result += k_units * light_d;
        if (w.specular) result += k_units * light_s;
    }
}

// The world, baked: split-sum (Karis 2013; corrected or not) or Unity's approximation
// (docs/model.md "Lighting": split_sum, split_sum_corrected, unity; ct_baked.h).
void baked_light(EnvMap env, string ibl, Surface sf, Geometry g, float metallic, Want w,
                 output color result)
{
    vector r;
    float x;
    baked_lookup(env, ibl, sf.g_model, sf.n, sf.v, g.NdotV, sf.pr, r, x);
    color L = prefiltered_radiance(env.bake, env.width, r, x, env.rotation, env.strength,
                                   env.bottom_up);
    color E = irradiance(env.bake, env.width, sf.n, env.rotation, env.strength, env.bottom_up);
    color spec_i = color(0), diff_i = color(0);
    if (ibl != "unity")
        indirect_split_sum(env, sf.g_model, sf.diffuse_model, g.NdotV, sf.pr, L, E,
                           sf.specColor, sf.diffColor, spec_i, diff_i);
    else
        indirect_unity(g.NdotV, sf.pr, sf.a, metallic, L, E, sf.specColor, sf.diffColor,
                       spec_i, diff_i);
    spec_i *= sf.k_ms;
    if (w.diffuse) result += diff_i;
    if (w.specular) result += spec_i;
}

// The world, reference (docs/model.md "Lighting": reference, "Environment sampling
// (reference mode)"): integral of f_r L_env (n.l) over the hemisphere by N BRDF samples
// (sample_brdf) and N environment samples (env_sample), balance heuristic: each adds
// f_r L_env (n.l) / (N (p_brdf + p_env)); a stratified set (radical inverse) under a random
// rotation per shading point (Cranley-Patterson). With `visibility` each sample traces a
// shadow ray (other objects occlude the world).
void reference_light(EnvMap env, Surface sf, point P, float p_spec, int N, int visibility,
                     int rays, point key, Want w, output color result)
{
    int use_env = (env.marginal != "" && env.conditional != "" && env.pdf_table != "");
    float r1 = hashnoise(key, STREAM_REFERENCE), r2 = hashnoise(key, STREAM_REFERENCE + 1.0);
    float r3 = hashnoise(key, STREAM_REFERENCE + 2.0);
    float r4 = hashnoise(key, STREAM_REFERENCE + 3.0);
    color sum_d = color(0), sum_s = color(0);
    for (int i = 0; i < 2 * N; i++) {
        int from_env = (i >= N);
        if (from_env && !use_env)
            break;
        int j = from_env ? i - N : i;
        float ua = min(wrap01((j + 0.5) / N + (from_env ? r3 : r1)), U_MAX);
        float ub = min(wrap01(radical_inverse2(j) + (from_env ? r4 : r2)), U_MAX);
        float uc = uniform01(key, STREAM_REFERENCE_PICK + i);
        float ud = uniform01(key, STREAM_REFERENCE_ENV + i);
        vector dir;
        float p_env = 0.0;
        if (from_env) {
            p_env = env_sample(env.marginal, env.conditional, env.pdf_table, env.rotation, ua,
                               ub, uc, ud, env.bottom_up, dir);
            if (p_env <= 0.0)
                continue;
        } else {
            dir = sample_brdf(sf.n, sf.v, sf.a, p_spec, uc, ua, ub);
        }
        float NdotL_i = dot(sf.n, dir);
        if (NdotL_i <= 0.0)
            continue;
        float p_brdf = brdf_pdf(sf.n, sf.v, dir, sf.a, p_spec);
        if (use_env && !from_env)
            p_env = env_pdf(env.pdf_table, dir, env.rotation, env.bottom_up);
        float p_sum = p_brdf + p_env;
        if (!(p_sum > 0.0))
            continue;
        if (visibility && shadowed(P, dir, FAR_AWAY, rays))
            continue;
        color L_env = env_radiance(env.file, env.width, dir, env.rotation, env.strength,
                                   env.bottom_up);
        color f_d_i, f_s_i;
        brdf_toward(sf, dir, f_d_i, f_s_i);
        float weight = NdotL_i / p_sum;
        sum_s += f_s_i * L_env * weight;
        sum_d += f_d_i * L_env * weight;
    }
    if (w.diffuse) result += sum_d / N;
    if (w.specular) result += sum_s / N;
}

// The scene transport's correction for the world and the shining light slots, one
// technique per sample (docs/model.md "The correction (a control variate)"; ct_correction.h):
// integral of (f_model - f_closure) L (n.l) dl.
color correction(Surface sf, point P, EnvMap env, Light lights[8], int rays, int N, point key)
{
    int active[8] = { 0, 0, 0, 0, 0, 0, 0, 0 };
    int n_active = 0;
    for (int i = 0; i < 8; i++) {
        if (shines(lights[i])) {
            active[n_active] = i;
            n_active += 1;
        }
    }
    return scene_correction(sf, P, env, env.file != "" && env.width > 0, lights, active,
                            n_active, rays, N, key);
}

// What the correction leaves to the closures (light from other objects): the residual
// albedo, integral of |f_model - f_closure| (n.l) dl (docs/model.md "The correction (a
// control variate)", the Residual Albedo output), by N GGX half vectors (ggx_half_pdf, for
// v.h > 0: the draws with v.h <= 0 are skipped).
color residual_estimate(Surface sf, int N, point key)
{
    float r1 = hashnoise(key, STREAM_RESIDUAL), r2 = hashnoise(key, STREAM_RESIDUAL + 1.0);
    color sum = color(0);
    for (int i = 0; i < N; i++) {
        float ua = min(wrap01((i + 0.5) / N + r1), U_MAX);
        float ub = min(wrap01(radical_inverse2(i) + r2), U_MAX);
        vector h = sample_ggx_half(sf.n, sf.a, ua, ub);
        vector dir = reflect(-sf.v, h);
        float VdotH_i = dot(sf.v, h);
        float NdotL_i = dot(sf.n, dir);
        if (NdotL_i <= 0.0 || VdotH_i <= 0.0)
            continue;
        float pdf = ggx_half_pdf(dot(sf.n, h), VdotH_i, sf.a);
        if (!(pdf > 0.0))
            continue;
        color f_d_i, f_s_i;
        brdf_toward(sf, dir, f_d_i, f_s_i);
        sum += abs(f_s_i) * NdotL_i / pdf;
    }
    return sum / N;
}

#endif // CT_ESTIMATORS_H
