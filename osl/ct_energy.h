// A part of the Cook-Torrance Lab shader, included by osl/cook_torrance.osl (the add-on
// inlines it when it loads the source: addon/core/osl_source.py, source()).
// The model's tables (DFG, multiple-scattering albedo) and the energy compensation
// (docs/model.md "Switches": energy).

#ifndef CT_ENERGY_H
#define CT_ENERGY_H

// The model's tables <table>_<G>.exr (dfg, ms) in a folder: texel (i, j) holds n.v = i/(N-1),
// pr = j/(N-1), row 0 at the top: texel centres sit at (k + 0.5)/N, so x in [0, 1] is looked
// up, bilinearly, at (x (N-1) + 0.5)/N. N is the bake's table size (ibl_bake.DFG_SIZE; a test
// checks that they agree).
#define DFG_SIZE 64

color model_table(string folder, string table, string g_model, float NdotV, float pr,
                  int bottom_up)
{
    float N = DFG_SIZE;
    return lookup(format("%s/%s_%s.exr", folder, table, g_model), (NdotV * (N - 1.0) + 0.5) / N,
                  (pr * (N - 1.0) + 0.5) / N, bottom_up, "clamp");
}

// Multiple scattering, by albedo scaling (Turquin 2019, "Practical multiple scattering
// compensation for microfacet models") with Kulla and Conty's (2017) Fresnel term, as Cycles
// compensates its GGX (microfacet_ggx_preserve_energy): the single-scattering lobe times
//   k_ms = 1 + F_ms (1 - E(mu_o)) / E(mu_o),  F_ms = F_avg E_avg / (1 - F_avg (1 - E_avg)),
//   F_avg = specColor + (1 - specColor)/21 (Schlick's cosine-weighted mean),
// E the directional albedo of f_s with F = 1 and E_avg its cosine-weighted mean: the table
// ms_<G> (core/ibl_bake.py ms_table) holds E in channel 0 and E_avg in channel 1, on the DFG
// table's axes. In a white furnace (F = 1) the lobe then reflects everything: E k_ms = 1.
color ms_factor(string tables, string g_model, float NdotV, float pr, color specColor,
                int bottom_up)
{
    color t = model_table(tables, "ms", g_model, NdotV, pr, bottom_up);
    float E = max(t[0], 1e-4), e_avg = t[1];
    color F_avg = specColor + (color(1.0) - specColor) / 21.0;
    color F_ms = F_avg * e_avg / max(color(1.0) - F_avg * (1.0 - e_avg), color(1e-6));
    return color(1.0) + F_ms * (1.0 - E) / E;
}


#endif // CT_ENERGY_H
