// A part of the Cook-Torrance Lab shader, included by osl/cook_torrance.osl (the add-on
// inlines it when it loads the source: addon/core/osl_source.py, source()).
// The shader's eight light slots (docs/model.md "Lights"): their parameters, declared by one
// macro per slot, and each slot as a Light (ct_lights.h).

#ifndef CT_LIGHT_SLOTS_H
#define CT_LIGHT_SLOTS_H

// One light slot's parameters (core.model LIGHTS: light<i>_<field>, labelled "Light <i> ...").
#define LIGHT_PARAMETERS(i) \
    int light##i##_type = 0 [[ string label = "Light " #i " Type", int min = 0, int max = 5 ]], \
    point light##i##_position = point(0) [[ string label = "Light " #i " Position" ]], \
    vector light##i##_direction = vector(0, 0, -1) [[ string label = "Light " #i " Direction" ]], \
    vector light##i##_axis_x = vector(0) [[ string label = "Light " #i " Axis X" ]], \
    vector light##i##_axis_y = vector(0) [[ string label = "Light " #i " Axis Y" ]], \
    color light##i##_color = color(0) [[ string label = "Light " #i " Color" ]], \
    float light##i##_size = 0.0 [[ string label = "Light " #i " Size" ]], \
    float light##i##_spot_size = M_PI [[ string label = "Light " #i " Spot Size" ]], \
    float light##i##_spot_blend = 0.0 [[ string label = "Light " #i " Spot Blend" ]], \
    int light##i##_shadow = 1 [[ string label = "Light " #i " Shadow", \
                                 string widget = "checkBox" ]],

#define LIGHT_SLOT(i) light_slot(light##i##_type, light##i##_position, light##i##_direction, \
    light##i##_axis_x, light##i##_axis_y, light##i##_color, light##i##_size, \
    light##i##_spot_size, light##i##_spot_blend, light##i##_shadow)

Light light_slot(int type, point position, vector direction, vector axis_x, vector axis_y,
                 color power, float size, float spot_size, float spot_blend, int shadow)
{
    Light lt;
    lt.type = type; lt.position = position; lt.direction = direction; lt.axis_x = axis_x;
    lt.axis_y = axis_y; lt.power = max(power, color(0));
    lt.size = (type == LIGHT_SUN) ? clamp(size, 0.0, M_PI) : max(size, 0.0);
    lt.spot_size = clamp(spot_size, 0.0, M_PI); lt.spot_blend = clamp(spot_blend, 0.0, 1.0);
    lt.shadow = shadow;
    return lt;
}

#endif // CT_LIGHT_SLOTS_H
