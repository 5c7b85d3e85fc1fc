// A part of the Cook-Torrance Lab shader, included by osl/cook_torrance.osl (the add-on
// inlines it when it loads the source: addon/core/osl_source.py, source()).
// The baked image-based lighting modes, split-sum and Unity's, over the world record EnvMap
// (ct_world.h) (docs/model.md "Lighting": split_sum, split_sum_corrected, unity).

#ifndef CT_BAKED_H
#define CT_BAKED_H

// Baked image-based lighting (addon/core/ibl_bake.py): levels specular_0..6 pre-filtered at
// pr = m / 6, irradiance E (a uniform world of radiance 1 gives pi), DFG tables.  Level 0 is
// the HDRI itself (W texels wide); level k and the irradiance are at most the widths below
// (ibl_bake.LEVEL_WIDTHS and IRRADIANCE_WIDTH; a test checks them), never wider than W.

#define IBL_LEVELS 7
#define LEVEL_1_WIDTH 512
#define LEVEL_2_WIDTH 256
#define LEVEL_3_WIDTH 128
#define LEVEL_4_WIDTH 64
#define LEVEL_5_WIDTH 64
#define LEVEL_6_WIDTH 64
#define IRRADIANCE_WIDTH 128

// A pre-filtered level's radiance toward r (a lat-long file `width` texels wide) times its
// weight w, read only where w > 0.
color weighted_level(string file, float w, float width, vector r, float rotation,
                     float strength, int bottom_up)
{
    if (w <= 0.0)
        return color(0);
    return w * env_radiance(file, width, r, rotation, strength, bottom_up);
}

// Irradiance E toward n.
color irradiance(string bake, float W, vector n, float rotation, float strength, int bottom_up)
{
    return env_radiance(format("%s/irradiance.exr", bake), min(W, IRRADIANCE_WIDTH), n,
                        rotation, strength, bottom_up);
}

// The pre-filtered radiance toward r at fractional level x (0 .. 6): the two levels around x
// blended linearly, sum_k max(0, 1 - |x - k|) L_k(r) (the node group's prefiltered()), for
// an HDRI W texels wide.  Each level is one call with its file named by a constant: from
// Blender 5.2 Cycles loads the textures a shader names while it optimises the shader, and a
// name that varies while shading reads no image.
color prefiltered_radiance(string bake, float W, vector r, float x, float rotation,
                           float strength, int bottom_up)
{
    float lx = clamp(x, 0.0, IBL_LEVELS - 1.0);
    return weighted_level(format("%s/specular_0.exr", bake), 1.0 - abs(lx), W, r,
                          rotation, strength, bottom_up)
         + weighted_level(format("%s/specular_1.exr", bake), 1.0 - abs(lx - 1.0),
                          min(W, LEVEL_1_WIDTH), r, rotation, strength, bottom_up)
         + weighted_level(format("%s/specular_2.exr", bake), 1.0 - abs(lx - 2.0),
                          min(W, LEVEL_2_WIDTH), r, rotation, strength, bottom_up)
         + weighted_level(format("%s/specular_3.exr", bake), 1.0 - abs(lx - 3.0),
                          min(W, LEVEL_3_WIDTH), r, rotation, strength, bottom_up)
         + weighted_level(format("%s/specular_4.exr", bake), 1.0 - abs(lx - 4.0),
                          min(W, LEVEL_4_WIDTH), r, rotation, strength, bottom_up)
         + weighted_level(format("%s/specular_5.exr", bake), 1.0 - abs(lx - 5.0),
                          min(W, LEVEL_5_WIDTH), r, rotation, strength, bottom_up)
         + weighted_level(format("%s/specular_6.exr", bake), 1.0 - abs(lx - 6.0),
                          min(W, LEVEL_6_WIDTH), r, rotation, strength, bottom_up);
}

// Each baked mode reads the pre-filtered levels once, toward r at fractional level x
// (baked_lookup), and the irradiance toward n; the modes differ in where they look (below)
// and in how they weight what they read (indirect_split_sum, indirect_unity).

// Split-sum (Karis 2013) looks toward the mirror direction r at level x = pr * 6.  With
// `corrected`, toward the lobe's dominant direction instead: for a rough lobe the reflected
// light comes from closer to n.  r' = normalize(mix(n, r, t)) as Lagarde and de Rousiers
// (2014, "Moving Frostbite to PBR", listing 22), but with t computed for this model's D and G
// (the lobe's centroid; channel 2 of ms_<G>, core/ibl_bake.py dominant_table) where they fit
// t = (1 - a)(sqrt(1 - a) + a) to Smith's G.  Unity's Standard shader
// (UnityImageBasedLighting.cginc) looks toward r at mip = pr (1.7 - 0.7 pr) * 6.
void baked_lookup(EnvMap env, string ibl, string g_model, vector n, vector vdir,
                  float NdotV, float pr, output vector r, output float x)
{
    r = reflect(-vdir, n);
    x = pr * (IBL_LEVELS - 1);
    if (ibl == "split_sum_corrected") {
        color ms = model_table(env.bake, "ms", g_model, NdotV, pr, env.bottom_up);
        r = normalize(mix(n, r, ms[2]));
    }
    if (ibl == "unity")
        x = pr * (1.7 - 0.7 * pr) * (IBL_LEVELS - 1);
}

// Split-sum: integral f_s L (n.l) dl ~ L (specColor A + B), L the pre-filtered radiance;
// diffuse: f_d's directional factor times E(n), i.e. diffColor E(n) / pi (x the Disney factor).
void indirect_split_sum(EnvMap env, string g_model, string diffuse_model, float NdotV,
                        float pr, color L, color E, color specColor, color diffColor,
                        output color spec, output color diff)
{
    color dfg = model_table(env.bake, "dfg", g_model, NdotV, pr, env.bottom_up);
    spec = L * (specColor * dfg[0] + dfg[1]);
    float k_diffuse = (diffuse_model == "lambert") ? 1.0 : dfg[2];
    diff = diffColor * E / M_PI * k_diffuse;
}

// Unity's Standard shader (UnityStandardBRDF.cginc, BRDF1_Unity_PBS): surfaceReduction =
// 1/(a^2 + 1), grazing = saturate(smoothness + 1 - oneMinusReflectivity), FresnelLerp with
// (1 - n.v)^5; diffuse = diffColor x irradiance (Unity's SH irradiance is E / pi).
void indirect_unity(float NdotV, float pr, float a, float metallic, color L, color E,
                    color specColor, color diffColor, output color spec, output color diff)
{
    float surface_reduction = 1.0 / (a * a + 1.0);
    float grazing = clamp((1.0 - pr) + 1.0 - 0.96 * (1.0 - metallic), 0.0, 1.0);
    spec = surface_reduction * L * mix(specColor, color(grazing), pow5(1.0 - NdotV));
    diff = diffColor * E / M_PI;
}

#endif // CT_BAKED_H
