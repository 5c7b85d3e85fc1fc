// A part of the Cook-Torrance Lab shader, included by osl/cook_torrance.osl (the add-on
// inlines it when it loads the source: addon/core/osl_source.py, source()).
// Blender's lights in Cycles' units, for the light slots (docs/model.md "Lights"): a light's
// sampler (sample_light) beside its density (light_along), and one light's MIS estimate.

#ifndef CT_LIGHTS_H
#define CT_LIGHTS_H

// Scene lights (docs/model.md "Lights"): Blender's Sun, Point, Spot and Area lights with Cycles'
// units. A slot's Color is colour x power (W; a Sun's strength, W/m^2), Direction the way it
// shines (the object's -Z), Size a Point or Spot's radius or a Sun's angular diameter, Axis
// X / Y half an Area light's extent. Radiance seen from a shading point:
//   Sun     S / (pi sin^2(angle/2)) inside the cone of half-angle angle/2 (delta when 0)
//   Point   Phi / (4 pi^2 r^2) from a disk of radius r facing the point (Cycles' soft falloff:
//           E = Phi cos / (4 pi (d^2 + r^2)) on the axis); delta Phi / (4 pi d^2) when r = 0
//   Spot    the Point's times smoothstep((cos phi - cos(S/2)) / ((1 - cos(S/2)) B)), phi the
//           angle between the spot's axis and the way from the point on the light to P
//   Area    Phi / (pi A) from its front (-Z) side, A = w h (rectangle) or pi w h / 4 (ellipse)

#define LIGHT_SUN 1
#define LIGHT_POINT 2
#define LIGHT_SPOT 3
#define LIGHT_AREA_RECTANGLE 4
#define LIGHT_AREA_ELLIPSE 5

// One light's slot inputs.
struct Light {
    int type; point position; vector direction; vector axis_x; vector axis_y; color power;
    float size; float spot_size; float spot_blend; int shadow;
};

// Light arriving from one direction: toward the light (dir), how far (dist), the radiance
// (Li) and the solid-angle density of choosing that direction by sampling the light (pdf);
// pdf = 0 marks a delta light, whose Li is then the irradiance facing it.
struct Incoming {
    vector dir; float dist; color Li; float pdf;
};

// Cycles' spot attenuation (spot_attenuation in kernel/light/spot.h).
float spot_factor(Light lt, vector to_point)
{
    if (lt.type != LIGHT_SPOT)
        return 1.0;
    float cos_half = cos(0.5 * lt.spot_size);
    float cos_phi = dot(normalize(lt.direction), to_point);
    float width = (1.0 - cos_half) * lt.spot_blend;
    if (width <= 0.0)
        return (cos_phi > cos_half) ? 1.0 : 0.0;
    return smoothstep(0.0, 1.0, (cos_phi - cos_half) / width);
}

// A slot that holds a light of a known type with some power (the others add nothing).
int shines(Light lt)
{
    return lt.type >= LIGHT_SUN && lt.type <= LIGHT_AREA_ELLIPSE && max_component(lt.power) > 0.0;
}

// A light of no extent: a Sun of angle 0, a Point or Spot of radius 0 (one direction).
int is_delta(Light lt)
{
    if (lt.type == LIGHT_SUN)
        return 0.5 * lt.size <= 1e-6;
    return (lt.type == LIGHT_POINT || lt.type == LIGHT_SPOT) && lt.size <= 1e-6;
}

float area_of(Light lt)
{
    float w = 2.0 * length(lt.axis_x), h = 2.0 * length(lt.axis_y);
    return (lt.type == LIGHT_AREA_ELLIPSE) ? M_PI * w * h / 4.0 : w * h;
}

// The radiance of a sized light toward P, and the density of reaching a point q on it at
// distance dist along dir (from P), with cos_l the cosine at the light's surface.
Incoming arriving(Light lt, point P, vector dir, float dist, float cos_l, float area)
{
    Incoming in;
    in.dir = dir; in.dist = dist; in.Li = color(0); in.pdf = 0.0;
    if (cos_l <= 0.0 || area <= 0.0)
        return in;
    in.pdf = dist * dist / (area * cos_l);
    if (lt.type == LIGHT_POINT || lt.type == LIGHT_SPOT)
        in.Li = lt.power / (4.0 * M_PI * area) * spot_factor(lt, -dir);
    else
        in.Li = lt.power / (M_PI * area);
    return in;
}

// 1 - cos(x) = 2 sin^2(x / 2): a cone's solid angle over 2 pi, without the cancellation of
// 1 - cos(x) in float (a Sun of 0.0005 rad, half angle 0.00025, would otherwise get a
// density off by 48%: 1 - cos is 5.96e-8 in float32, 3.125e-8 in fact; and one under about
// 0.00049 rad, where it rounds to 0, none at all).
float cone_1mcos(float x)
{
    float s = sin(0.5 * x);
    return 2.0 * s * s;
}

// Chooses a direction toward the light for P (u1, u2 uniform in [0, 1)).
Incoming sample_light(Light lt, point P, float u1, float u2)
{
    Incoming in;
    in.dir = vector(0, 0, 1); in.dist = FAR_AWAY; in.Li = color(0); in.pdf = 0.0;
    if (lt.type == LIGHT_SUN) {
        vector axis = -normalize(lt.direction);
        float half_angle = 0.5 * lt.size;
        if (is_delta(lt)) {
            in.dir = axis;
            in.Li = lt.power;
            return in;
        }
        // uniform in the cone: density 1 / (2 pi (1 - cos(half_angle))), 1 - cos(x) written
        // 2 sin^2(x / 2) (cone_1mcos), and sin from 1 - c: exact in float for small Suns
        float omc = cone_1mcos(half_angle);
        float one_minus_c = u1 * omc;
        float c = 1.0 - one_minus_c;
        float s = sqrt(max(0.0, one_minus_c * (2.0 - one_minus_c)));
        vector t, b;
        make_frame(axis, t, b);
        in.dir = normalize(s * cos(M_2PI * u2) * t + s * sin(M_2PI * u2) * b + c * axis);
        in.pdf = 1.0 / (M_2PI * omc);
        in.Li = lt.power / (M_PI * pow(sin(half_angle), 2));
        return in;
    }
    vector to_light = lt.position - P;
    float d = length(to_light);
    if (d <= 1e-9)
        return in;
    if (lt.type == LIGHT_POINT || lt.type == LIGHT_SPOT) {
        if (is_delta(lt)) {
            in.dir = to_light / d;
            in.dist = d;
            in.Li = lt.power / (4.0 * M_PI * d * d) * spot_factor(lt, -in.dir);
            return in;
        }
        vector w = -to_light / d;              // the disk faces P
        vector t, b;
        make_frame(w, t, b);
        float x, y;
        concentric_disk(u1, u2, x, y);
        point q = lt.position + lt.size * (x * t + y * b);
        vector dq = q - P;
        float dist = length(dq);
        return arriving(lt, P, dq / dist, dist, dot(w, -dq / dist), M_PI * lt.size * lt.size);
    }
    point q;
    if (lt.type == LIGHT_AREA_ELLIPSE) {
        float x, y;
        concentric_disk(u1, u2, x, y);
        q = lt.position + x * lt.axis_x + y * lt.axis_y;
    } else {
        q = lt.position + (2.0 * u1 - 1.0) * lt.axis_x + (2.0 * u2 - 1.0) * lt.axis_y;
    }
    vector dq = q - P;
    float dist = length(dq);
    if (dist <= 1e-9)
        return in;
    return arriving(lt, P, dq / dist, dist, dot(normalize(lt.direction), -dq / dist),
                    area_of(lt));
}

// The light seen from P along dir (a direction chosen by sampling the BRDF): its radiance
// and sample_light's density for that direction; Li = 0 where dir misses the light.
Incoming light_along(Light lt, point P, vector dir)
{
    Incoming in;
    in.dir = dir; in.dist = FAR_AWAY; in.Li = color(0); in.pdf = 0.0;
    if (lt.type == LIGHT_SUN) {
        float half_angle = 0.5 * lt.size;
        vector axis = -normalize(lt.direction);
        // inside the cone: the sine of the angle to the axis (|dir x axis|, exact in float for
        // small angles, where 1 - dot is not) within sin(half_angle), on the axis' side
        if (!is_delta(lt) && dot(dir, axis) > 0.0 &&
            length(cross(dir, axis)) <= sin(half_angle)) {
            in.pdf = 1.0 / (M_2PI * cone_1mcos(half_angle));
            in.Li = lt.power / (M_PI * pow(sin(half_angle), 2));
        }
        return in;
    }
    vector to_light = lt.position - P;
    float d = length(to_light);
    vector nl;                                 // the emitting side's normal
    float area;
    if (lt.type == LIGHT_POINT || lt.type == LIGHT_SPOT) {
        if (is_delta(lt) || d <= 1e-9)
            return in;
        nl = -to_light / d;
        area = M_PI * lt.size * lt.size;
    } else {
        nl = normalize(lt.direction);
        area = area_of(lt);
    }
    float denom = dot(dir, nl);
    if (denom >= 0.0)
        return in;                             // parallel, or the light's back
    float dist = dot(lt.position - P, nl) / denom;
    if (dist <= 0.0)
        return in;
    vector offset = P + dist * dir - lt.position;
    if (lt.type == LIGHT_POINT || lt.type == LIGHT_SPOT) {
        if (length(offset) > lt.size)
            return in;
    } else {
        float x = dot(offset, lt.axis_x) / max(dot(lt.axis_x, lt.axis_x), 1e-20);
        float y = dot(offset, lt.axis_y) / max(dot(lt.axis_y, lt.axis_y), 1e-20);
        if (lt.type == LIGHT_AREA_ELLIPSE ? (x * x + y * y > 1.0)
                                           : (abs(x) > 1.0 || abs(y) > 1.0))
            return in;
    }
    return arriving(lt, P, dir, dist, -denom, area);
}

// One light's reflected radiance, diffuse and specular: one sample of the light and one of
// the BRDF, combined with the balance heuristic (Veach 1995), each adding
// f_r Li (n.l) / (p_light + p_brdf); a delta light takes its one direction alone, adding
// f_r E (n.l). Shadow rays as shadowed(); u holds five uniform numbers.
void shade_light(Light lt, point P, Surface sf, float p_spec, int rays, float u[5],
                 output color sum_d, output color sum_s)
{
    sum_d = color(0);
    sum_s = color(0);
    if (!shines(lt))
        return;
    int delta = is_delta(lt);
    color f_d, f_s;
    Incoming in = sample_light(lt, P, u[0], u[1]);
    vector n = sf.n, v = sf.v;
    float cos_l = dot(n, in.dir);
    if (cos_l > 0.0 && max_component(in.Li) > 0.0 &&
        !(lt.shadow && shadowed(P, in.dir, in.dist, rays))) {
        brdf_toward(sf, in.dir, f_d, f_s);
        float w = delta ? cos_l : cos_l / (in.pdf + brdf_pdf(n, v, in.dir, sf.a, p_spec));
        sum_d += f_d * in.Li * w;
        sum_s += f_s * in.Li * w;
    }
    if (delta)
        return;
    vector dir = sample_brdf(n, v, sf.a, p_spec, u[2], u[3], u[4]);
    cos_l = dot(n, dir);
    if (cos_l <= 0.0)
        return;
    Incoming hit = light_along(lt, P, dir);
    if (hit.pdf <= 0.0 || max_component(hit.Li) <= 0.0 ||
        (lt.shadow && shadowed(P, dir, hit.dist, rays)))
        return;
    brdf_toward(sf, dir, f_d, f_s);
    float w = cos_l / (hit.pdf + brdf_pdf(n, v, dir, sf.a, p_spec));
    sum_d += f_d * hit.Li * w;
    sum_s += f_s * hit.Li * w;
}
#endif // CT_LIGHTS_H
