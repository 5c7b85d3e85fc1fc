// A part of the Cook-Torrance Lab shader, included by osl/cook_torrance.osl (the add-on
// inlines it when it loads the source: addon/core/osl_source.py, source()).
// The scene transport's correction by the one-sample model of multiple importance sampling
// (docs/model.md "The correction"): each sample draws ONE technique, the world's or one
// light's, instead of every technique of every light and the world as the lab does.

#ifndef CT_CORRECTION_H
#define CT_CORRECTION_H

// One sample of integral (f_model - f_closure) L_world (n.l) dl. The technique is a
// direction from GGX's visible normals or an environment direction, each with probability
// 1/2 (the GGX one alone without the tables); the one-sample balance heuristic (Veach 1997,
// sec. 9.2.4) weighs the draw by the mixture's density:
//   f L (n.l) / (c_brdf p_brdf + c_env p_env).
// The correction has no diffuse part (ct_transport.h: both diffuse closures are the model's),
// so the BRDF technique draws the GGX lobe alone, by its visible normals (ct_sampling.h): the
// difference of two G is largest at grazing views, where D (n.h) sampling is at its worst.
// u: five numbers in [0, 1).
color world_correction_sample(Surface sf, point P, EnvMap env, int rays, float u[5])
{
    int tables = (env.marginal != "" && env.conditional != "" && env.pdf_table != "");
    float c_env = tables ? 0.5 : 0.0;
    vector dir;
    float p_env = 0.0;
    if (u[0] < c_env) {
        p_env = env_sample(env.marginal, env.conditional, env.pdf_table, env.rotation, u[1],
                           u[2], u[3], u[4], env.bottom_up, dir);
        if (p_env <= 0.0)
            return color(0);
    } else {
        dir = sample_ggx_visible(sf.n, sf.v, sf.a, u[1], u[2]);
        if (tables)
            p_env = env_pdf(env.pdf_table, dir, env.rotation, env.bottom_up);
    }
    float cos_l = dot(sf.n, dir);
    if (cos_l <= 0.0)
        return color(0);
    float p = c_env * p_env + (1.0 - c_env) * ggx_visible_pdf(sf.n, sf.v, dir, sf.a);
    if (!(p > 0.0) || shadowed(P, dir, FAR_AWAY, rays))
        return color(0);
    color f_d, f_s;
    brdf_toward(sf, dir, f_d, f_s);
    return (f_d + f_s) * env_radiance(env.file, env.width, dir, env.rotation, env.strength,
                                      env.bottom_up) * cos_l / p;
}

// One sample of integral (f_model - f_closure) L_light (n.l) dl for one light slot: a point
// on the light or a direction from GGX's visible normals, each with probability 1/2 (a light
// of no size, a point, a spot or a Sun of angle 0: its one direction), weighed as above by
// c_light p_light + c_brdf p_brdf (ct_lights.h for the light's density and radiance); its
// shadow ray, up to the light, where the slot casts shadows.
color light_correction_sample(Surface sf, point P, Light lt, int rays, float u[5])
{
    int delta = is_delta(lt);
    float c_light = delta ? 1.0 : 0.5;
    Incoming in;
    if (u[0] < c_light) {
        in = sample_light(lt, P, u[1], u[2]);
    } else {
        in = light_along(lt, P, sample_ggx_visible(sf.n, sf.v, sf.a, u[1], u[2]));
        if (in.pdf <= 0.0)
            return color(0);    // the direction misses the light
    }
    float cos_l = dot(sf.n, in.dir);
    if (cos_l <= 0.0 || max_component(in.Li) <= 0.0 ||
        (lt.shadow && shadowed(P, in.dir, in.dist, rays)))
        return color(0);
    color f_d, f_s;
    brdf_toward(sf, in.dir, f_d, f_s);
    float w = delta ? cos_l
                    : cos_l / (c_light * in.pdf +
                               (1.0 - c_light) * ggx_visible_pdf(sf.n, sf.v, in.dir, sf.a));
    return (f_d + f_s) * in.Li * w;
}

// The correction for the world and the light slots, N samples (the Env Samples input), one
// technique each: the world with probability q (1/2, or 1 without lights, 0 without a world)
// and light slot k with (1 - q) / n, stratified over the N samples; each draw divided by its
// probability, so the mean is the integral over the world and all lights (an unbiased
// estimate; its noise is added to Cycles' own, which dominates: bench/scene_samples.py).
// lights: the slots, of which `active` lists the n that shine.
color scene_correction(Surface sf, point P, EnvMap env, int world, Light lights[8],
                       int active[8], int n, int rays, int N, point key)
{
    float q = world ? ((n > 0) ? 0.5 : 1.0) : 0.0;
    float r = hashnoise(key, STREAM_CORRECTION);
    color sum = color(0);
    for (int s = 0; s < N; s++) {
        float u[5];
        for (int k = 0; k < 5; k++)
            u[k] = uniform01(key, STREAM_CORRECTION_SAMPLES + 8 * s + k);
        float pick = wrap01((s + 0.5) / N + r);
        if (pick < q) {
            sum += world_correction_sample(sf, P, env, rays, u) / q;
        } else if (n > 0) {
            int k = min((int)floor((pick - q) / (1.0 - q) * n), n - 1);
            sum += light_correction_sample(sf, P, lights[active[k]], rays, u) * (n / (1.0 - q));
        }
    }
    return sum / N;
}


#endif // CT_CORRECTION_H
