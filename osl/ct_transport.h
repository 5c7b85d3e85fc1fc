// A part of the Cook-Torrance Lab shader, included by osl/cook_torrance.osl (the add-on
// inlines it when it loads the source: addon/core/osl_source.py, source()).
// The model as a struct, toward one direction, and as Cycles closures: the scene transport
// (docs/model.md "Light transport"); the shadow ray every estimator traces ("Shadows").

#ifndef CT_TRANSPORT_H
#define CT_TRANSPORT_H

#define FAR_AWAY 1.0e30  // a shadow ray's length toward the world and a Sun

// The model's BRDF, as a struct so that helpers can take it whole.
// `closures` marks the scene transport's correction (below): the BRDF is then what Cycles'
// closures leave out of the model, f_model - f_closure.
struct Surface {
    vector n; vector v; float a; float pr; color specColor; color diffColor;
    string g_model; string diffuse_model; color k_ms; int closures;
};

// f_d and f_s of the chosen G and diffuse toward dir (f_s is 0 below the surface), f_s times
// the multiple-scattering factor k_ms (1 when energy is not compensated). For the scene
// transport's correction (sf.closures), the model minus the closures scene_closures() makes:
// f_s - D F G_Smith / (4 (n.l)(n.v)), and no diffuse (Burley's and Lambert's closures are the
// model's diffuse exactly).
void brdf_toward(Surface sf, vector dir, output color f_d, output color f_s)
{
    Geometry g = geometry_of(sf.n, sf.v, dir);
    float D = D_GGX(g.NdotH, sf.a);
    color F = F_Schlick(sf.specColor, g.LdotH);
    f_s = sf.k_ms * specular_brdf(D, F, G_term(sf.g_model, g.NdotH, g.NdotV, g.NdotL, g.VdotH,
                                               sf.a), g.NdotL, g.NdotV);
    f_d = diffuse_brdf(sf.diffuse_model, sf.diffColor, g.NdotL, g.NdotV, g.LdotH, sf.pr);
    if (sf.closures) {
        f_s -= specular_brdf(D, F, G_SmithGGXCorrelated(g.NdotV, g.NdotL, sf.a), g.NdotL,
                             g.NdotV);
        f_d = color(0);
    }
}

// The scene transport (docs/model.md "Light transport"): the model as Cycles closures, path
// traced by Cycles. generalized_schlick_bsdf with f0 = specColor, f90 = 1 and exponent 5 is
// GGX D (its roughness arguments are alpha), Schlick's F and the height-correlated Smith G
// without energy compensation; burley_diffuse_bsdf is Unity's DisneyDiffuse / pi with the
// perceptual roughness, diffuse() Lambert's. The two are added (layer() would scale the
// diffuse by 1 - the specular albedo, which the model does not).
closure color scene_closures(Surface sf)
{
    closure color spec = generalized_schlick_bsdf(sf.n, vector(0), color(1), color(0), sf.a,
                                                  sf.a, sf.specColor, color(1), 5.0, "ggx");
    if (sf.diffuse_model == "lambert")
        return spec + sf.diffColor * diffuse(sf.n);
    return spec + burley_diffuse_bsdf(sf.n, sf.diffColor, sf.pr);
}


// Shadow ray from the shading point toward dir, up to dist (docs/model.md "Shadows"). With
// no minimum distance and the origin exactly P, Cycles skips the primitive the ray leaves
// (OSLRenderServices::trace), and maxdist stops it at the light, so nothing beyond the light
// counts. A ray that leaves under its facet (dot(Ng, dir) <= 0, which only the smooth shading
// normal allows) would enter its own object at once; like Cycles' shadow-terminator offset,
// it is not shadowed by that. rays = 0 traces nothing: for a scene whose objects shadow
// neither each other nor themselves (the matrix's convex spheres when their mutual shadows
// are off, as Principled's are then).
int shadowed(point P, vector dir, float dist, int rays)
{
    if (!rays || dot(Ng, dir) <= 0.0)
        return 0;
    return trace(P, dir, "maxdist", (dist >= FAR_AWAY) ? FAR_AWAY : dist * (1.0 - 1e-4));
}

#endif // CT_TRANSPORT_H
