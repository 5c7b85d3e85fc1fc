// A part of the Cook-Torrance Lab shader, included by osl/cook_torrance.osl (the add-on
// inlines it when it loads the source: addon/core/osl_source.py, source()).
// The world: Blender's equirectangular mapping, texture lookups and the environment sampler
// (docs/model.md "Lighting", "Environment sampling", "Textures in OSL").

#ifndef CT_WORLD_H
#define CT_WORLD_H

// ---------------------------------------------------------------------------------------
// The world: Blender's Environment Texture mapping (equirectangular) and its Z rotation.

vector rotate_z(vector d, float angle)
{
    float c = cos(angle), s = sin(angle);
    return vector(c * d[0] - s * d[1], s * d[0] + c * d[1], d[2]);
}

// Blender: s = 0.5 - atan2(d.y, d.x) / 2pi,  t = 0.5 + atan2(d.z, hypot(d.x, d.y)) / pi,
// with t = 0 at the image's bottom row.  Here t is counted from the top row (row 0 of the
// file), as the bake and the tables index their rows; lookup() turns it as Cycles needs.
void direction_to_st(vector d, output float s, output float t)
{
    s = 0.5 - atan2(d[1], d[0]) / M_2PI;
    t = 0.5 - atan2(d[2], hypot(d[0], d[1])) / M_PI;
}

vector st_to_direction(float s, float t)
{
    float phi = (0.5 - s) * M_2PI;
    float elevation = (0.5 - t) * M_PI;
    return vector(cos(elevation) * cos(phi), cos(elevation) * sin(phi), sin(elevation));
}

// Reading a texture file (docs/model.md, "Textures in OSL").  Up to Blender 5.1, texture()
// is OpenImageIO's: t = 0 is the file's top row and the "interp"/"swrap" options apply.
// From 5.2, Cycles' own image manager serves it: t = 0 is the bottom row, filtering is always
// bilinear and edges always clamp.  So every lookup comes here, t (from the top) is turned
// over where `bottom_up` says so (the add-on sets it for the running Blender), and tables are
// read at texel centres, where bilinear filtering returns the texel itself.
color lookup(string file, float s, float t, int bottom_up, string swrap)
{
    return texture(file, s, bottom_up ? 1.0 - t : t, 0, 0, 0, 0, "interp", "linear",
                   "swrap", swrap, "twrap", "clamp", "missingcolor", color(0));
}

// Texel (i, j) of a table W x H, row j = 0 at the top: read at its centre.  (The sizes are
// the add-on's constants, below: gettextureinfo() crashes Cycles in Blender 5.2.)
float table_texel(string table, float i, float j, float W, float H, int bottom_up)
{
    color c = lookup(table, (i + 0.5) / W, (j + 0.5) / H, bottom_up, "clamp");
    return c[0];
}

// Bilinear lookup of a lat-long image W texels wide (W/2 high) at (s, t), s periodic and t
// clamped to the first and last rows' centres, as Blender's Environment Texture (and the node
// group) filter it.  Inside the image one filtered texture() call does it; within half a texel
// of an edge it is written out from four texel centres, since from Blender 5.2 texture() takes
// the texels beyond an edge as black, and never wraps.
color latlong_texture(string file, float s, float t, float W, int bottom_up)
{
    float H = floor(W / 2);
    float x = wrap01(s) * W - 0.5;
    float y = t * H - 0.5;
    if (x >= 0.0 && x <= W - 1.0 && y >= 0.0 && y <= H - 1.0)
        return lookup(file, (x + 0.5) / W, (y + 0.5) / H, bottom_up, "periodic");
    y = clamp(y, 0.0, H - 1.0);
    float i0 = floor(x), j0 = floor(y);
    float fx = x - i0, fy = y - j0;
    float i1 = (i0 + 1.0 >= W) ? 0.0 : i0 + 1.0;
    if (i0 < 0.0) i0 = W - 1.0;
    float j1 = min(j0 + 1.0, H - 1.0);
    color c00 = lookup(file, (i0 + 0.5) / W, (j0 + 0.5) / H, bottom_up, "clamp");
    color c10 = lookup(file, (i1 + 0.5) / W, (j0 + 0.5) / H, bottom_up, "clamp");
    color c01 = lookup(file, (i0 + 0.5) / W, (j1 + 0.5) / H, bottom_up, "clamp");
    color c11 = lookup(file, (i1 + 0.5) / W, (j1 + 0.5) / H, bottom_up, "clamp");
    return mix(mix(c00, c10, fx), mix(c01, c11, fx), fy);
}

// Radiance of the world in world direction d, from a lat-long file W texels wide: the
// Mapping node rotates the lookup vector.
color env_radiance(string file, float W, vector d, float rotation, float strength,
                   int bottom_up)
{
    float s, t;
    direction_to_st(rotate_z(d, rotation), s, t);
    return latlong_texture(file, s, t, W, bottom_up) * strength;
}

// The environment sampler's tables (addon/core/env_importance.py): a fixed grid of tiles and
// inverse CDFs of ENV_TABLE_SIZE entries (a test checks these against the add-on's).
#define ENV_TABLE_SIZE 4096
#define ENV_TILE_ROWS 128
#define ENV_TILE_COLS 256

// Density of the environment sampler in solid angle, for a world direction.
// The table holds the density q with respect to (s, t); d(omega) = 2 pi^2 cos(elevation) ds dt.
float env_pdf(string pdf_table, vector d, float rotation, int bottom_up)
{
    vector dt = rotate_z(d, rotation);
    float s, t;
    direction_to_st(dt, s, t);
    float cos_elev = hypot(dt[0], dt[1]);
    if (cos_elev < 1e-6)
        return 0.0;
    float col = min(floor(wrap01(s) * ENV_TILE_COLS), ENV_TILE_COLS - 1.0);
    float row = clamp(floor(t * ENV_TILE_ROWS), 0.0, ENV_TILE_ROWS - 1.0);
    float q = table_texel(pdf_table, col, row, ENV_TILE_COLS, ENV_TILE_ROWS, bottom_up);
    return q / (2.0 * M_PI * M_PI * cos_elev);
}

// Draws a world direction from the environment tables: a tile row from the marginal
// inverse CDF (entry floor(u1 M)), a column from that row's conditional inverse CDF, then a
// uniform point inside the tile.  Returns the solid-angle density of the draw.
float env_sample(string marginal, string conditional, string pdf_table, float rotation,
                 float u1, float u2, float u3, float u4, int bottom_up, output vector d)
{
    float M = ENV_TABLE_SIZE, R = ENV_TILE_ROWS, C = ENV_TILE_COLS;
    float row = table_texel(marginal, floor(u1 * M), 0.0, M, 1.0, bottom_up);
    float col = table_texel(conditional, floor(u2 * M), row, M, R, bottom_up);
    float s = (col + u3) / C;
    float t = (row + u4) / R;
    vector dt = st_to_direction(s, t);
    d = rotate_z(dt, -rotation);
    float cos_elev = hypot(dt[0], dt[1]);
    if (cos_elev < 1e-6)
        return 0.0;
    return table_texel(pdf_table, col, row, C, R, bottom_up) / (2.0 * M_PI * M_PI * cos_elev);
}

// The world, one record for every estimator: the equirectangular image (file, its width),
// its mapping (rotation about Z, strength, texture rows bottom-up), the environment
// sampler's tables, and the baked split-sum files (bake: ibl_bake's folder, ct_baked.h).
struct EnvMap {
    string file; float width; float rotation; float strength;
    string marginal; string conditional; string pdf_table; int bottom_up; string bake;
};

EnvMap env_map(string file, int width, float rotation, float strength, string marginal,
               string conditional, string pdf_table, int bottom_up, string bake)
{
    EnvMap env;
    env.file = file; env.width = width; env.rotation = rotation; env.strength = strength;
    env.marginal = marginal; env.conditional = conditional; env.pdf_table = pdf_table;
    env.bottom_up = bottom_up; env.bake = bake;
    return env;
}

#endif // CT_WORLD_H
