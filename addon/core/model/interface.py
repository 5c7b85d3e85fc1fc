"""The model's interface, written once (docs/model.md): its surface inputs, switches, views,
the key-light and world inputs, the light slots, the OSL shader's own inputs and the outputs,
each with its type, default, range and its names in OSL and in the node group.

Every implementation reads these names from here: the OSL shader's parameters
(tests/render/test_interface.py checks the shader against this table), the node group's interface
(addon/blender/node_group.py builds its sockets from INPUTS), the model-node API, light sync,
the command line and the UI. Like MaterialX's node definitions, one interface serves
implementations in two languages.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from .words import (
    BAKED_IBL_MODES,
    DEFAULT_ALBEDO,
    DIFFUSE_MODELS,
    ENERGY_MODES,
    G_MODELS,
    IBL_MODES,
    LIGHT_SLOTS,
    LIGHT_TRANSPORTS,
    LIGHT_TYPE_CODES,
    UNITS,
    VIEWS,
)


@dataclass(frozen=True)
class Input:
    """One input of the model node.

    ``key`` names it in Python (a ModelOptions or Lighting field, or a surface input);
    ``label`` is its name in the UI, the node group's socket and the OSL parameter's label;
    ``osl`` the OSL parameter (None where the shader has none); ``group`` the node group's
    socket (None where the group has none). Switches are strings in OSL and 0/1 integers in
    the group (``values[i]`` for i), so they have both names."""

    key: str
    label: str
    kind: str  # FLOAT, INT, RGBA, VECTOR, STRING
    default: object
    tooltip: str
    osl: str | None = None
    group: str | None = None
    min: float = 0.0
    max: float = 1.0
    values: tuple = ()  # a switch's values (the first is the default)


def _surface(key, label, kind, default, tooltip, osl, lo=0.0, hi=1.0):
    return Input(key, label, kind, default, tooltip, osl=osl, group=label, min=lo, max=hi)


# The surface inputs: the values a material gives the model.
SURFACE = (
    _surface(
        "albedo", "Albedo", "RGBA", DEFAULT_ALBEDO + (1.0,), "Base colour, linear RGB", "albedo"
    ),
    _surface("metallic", "Metallic", "FLOAT", 0.0, "Metalness", "metallic"),
    _surface(
        "smoothness",
        "Smoothness",
        "FLOAT",
        0.5,
        "Unity's smoothness: perceptual roughness = 1 - smoothness",
        "smoothness",
    ),
    _surface(
        "normal",
        "Normal",
        "VECTOR",
        (0.0, 0.0, 0.0),
        "Shading normal (world space); unconnected: the geometry's",
        "shading_normal",
        -1.0,
        1.0,
    ),
)

# The view and the switches: strings in OSL, indices / 0-1 integers in the node group.
OPTIONS = (
    Input(
        "view",
        "View",
        "INT",
        0,
        ", ".join(f"{i} {v}" for i, v in enumerate(VIEWS)),
        osl="view",
        group="View",
        min=0,
        max=len(VIEWS) - 1,
        values=VIEWS,
    ),
    Input(
        "g_model",
        "G",
        "INT",
        0,
        "0: Cook-Torrance G; 1: height-correlated Smith G; 2: Unity's Smith joint visibility",
        osl="g_model",
        group="G Model",
        max=len(G_MODELS) - 1,
        values=G_MODELS,
    ),
    Input(
        "diffuse_model",
        "Diffuse",
        "INT",
        0,
        "0: Disney diffuse; 1: Lambert",
        osl="diffuse_model",
        group="Diffuse Lambert",
        values=DIFFUSE_MODELS,
    ),
    Input(
        "units",
        "Units",
        "INT",
        0,
        "0: physical; 1: Unity (x pi on direct light and the BRDF views)",
        osl="units",
        group="Units Unity",
        values=UNITS,
    ),
    Input(
        "energy",
        "Energy",
        "INT",
        0,
        "0: single scattering (the seed's model); 1: Kulla-Conty multiple scattering",
        osl="energy",
        group="Energy Compensated",
        values=ENERGY_MODES,
    ),
    # the group has no reference mode: IBL Mode indexes BAKED_IBL_MODES
    Input(
        "ibl",
        "IBL",
        "INT",
        0,
        "0: split-sum; 1: Unity's approximation; 2: split-sum toward the dominant direction",
        osl="ibl",
        group="IBL Mode",
        max=len(BAKED_IBL_MODES) - 1,
        values=IBL_MODES,
    ),
    Input(
        "light_transport",
        "Light Transport",
        "INT",
        0,
        "0: lab (the model lights itself and emits the result); 1: scene (Cycles closures, "
        "path traced, plus the model's correction for the world and the lights)",
        osl="light_transport",
        group="Light Transport Scene",
        values=LIGHT_TRANSPORTS,
    ),
)

# How far the scene transport's correction reaches: both implementations.
TRANSPORT = (
    Input(
        "correction_depth",
        "Correction Depth",
        "INT",
        2,
        "The scene transport's correction at hits of a ray depth below this (1: camera hits, "
        "2: and the first bounce; a number above the scene's bounces: every hit); deeper, the "
        "closures alone",
        osl="correction_depth",
        group="Correction Depth",
        min=1,
        max=1024,
    ),
)

# The key light and the world, as drivers and the sync handler keep them (light_sync).
LIGHTING = (
    Input(
        "sun_to_light",
        "Sun Direction",
        "VECTOR",
        (0.0, 0.0, 1.0),
        "Direction toward the key Sun (a driver keeps it in sync)",
        osl="sun_to_light",
        group="Sun Direction",
        min=-1.0,
        max=1.0,
    ),
    Input(
        "sun_irradiance",
        "Sun Irradiance",
        "RGBA",
        (0.0, 0.0, 0.0, 1.0),
        "Sun strength x colour (W/m^2)",
        osl="sun_irradiance",
        group="Sun Irradiance",
        max=1e6,
    ),
    Input(
        "hdri_strength",
        "HDRI Strength",
        "FLOAT",
        1.0,
        "The world's Background strength",
        osl="hdri_strength",
        group="HDRI Strength",
        max=1e6,
    ),
    Input(
        "hdri_rotation",
        "HDRI Rotation",
        "FLOAT",
        0.0,
        "The world Mapping's Z rotation (radians)",
        osl="hdri_rotation",
        group="HDRI Rotation",
        min=-1000.0,
        max=1000.0,
    ),
)


def _light_inputs(slot: int) -> tuple:
    """The inputs of light slot ``slot`` (1 .. LIGHT_SLOTS): OSL ``light<slot>_<field>``,
    group socket "Light <slot> <Label>" (the shadow switch is OSL's only)."""
    types = ", ".join(f"{v} {k.title().replace('_', ' ')}" for k, v in LIGHT_TYPE_CODES.items())
    fields = (
        ("type", "Type", "INT", 0, f"0 empty, {types}", 0, 5),
        ("position", "Position", "VECTOR", (0.0, 0.0, 0.0), "World location (m)", -1e6, 1e6),
        (
            "direction",
            "Direction",
            "VECTOR",
            (0.0, 0.0, -1.0),
            "World direction the light shines: its object's -Z axis",
            -1.0,
            1.0,
        ),
        (
            "axis_x",
            "Axis X",
            "VECTOR",
            (0.0, 0.0, 0.0),
            "Area: half its size along its X axis, world space (m)",
            -1e6,
            1e6,
        ),
        (
            "axis_y",
            "Axis Y",
            "VECTOR",
            (0.0, 0.0, 0.0),
            "Area: half its size along its Y axis, world space (m)",
            -1e6,
            1e6,
        ),
        (
            "color",
            "Color",
            "RGBA",
            (0.0, 0.0, 0.0, 1.0),
            "Colour x power x 2^exposure (W; a Sun's strength in W/m^2)",
            0.0,
            1e9,
        ),
        (
            "size",
            "Size",
            "FLOAT",
            0.0,
            "Point and Spot: radius (m); Sun: angular diameter (radians)",
            0.0,
            1e6,
        ),
        (
            "spot_size",
            "Spot Size",
            "FLOAT",
            3.141592653589793,
            "Spot: the cone's full angle (radians)",
            0.0,
            3.141592653589793,
        ),
        ("spot_blend", "Spot Blend", "FLOAT", 0.0, "Spot: the soft edge's blend", 0.0, 1.0),
    )
    inputs = tuple(
        Input(
            f"light{slot}_{key}",
            f"Light {slot} {label}",
            kind,
            default,
            tip,
            osl=f"light{slot}_{key}",
            group=f"Light {slot} {label}",
            min=lo,
            max=hi,
        )
        for key, label, kind, default, tip, lo, hi in fields
    )
    return inputs + (
        Input(
            f"light{slot}_shadow",
            f"Light {slot} Shadow",
            "INT",
            1,
            "Trace the light's shadow (its Cast Shadow)",
            osl=f"light{slot}_shadow",
        ),
    )


LIGHTS = tuple(i for slot in range(1, LIGHT_SLOTS + 1) for i in _light_inputs(slot))
LIGHT_FIELDS = tuple(i.key.split("_", 1)[1] for i in _light_inputs(1))


def light_key(slot: int, field: str) -> str:
    """The input key of ``field`` in light slot ``slot`` (1-based)."""
    return f"light{slot}_{field}"


# What only the OSL shader has: files (a node cannot be given a file by a driver), the
# reference integrator's settings, and how this Blender's texture() counts rows.
OSL_ONLY = (
    Input("sun_shadow", "Sun Shadow", "INT", 1, "Trace the key Sun's shadow", osl="sun_shadow"),
    Input(
        "ibl_bake",
        "IBL Bake Folder",
        "STRING",
        "",
        "The split-sum bake (core.ibl_bake)",
        osl="ibl_bake",
    ),
    Input("hdri", "HDRI", "STRING", "", "The world's equirectangular HDRI", osl="hdri"),
    Input(
        "tables",
        "Tables Folder",
        "STRING",
        "",
        "The model's DFG and multiple-scattering tables (core.ibl_bake.tables_folder)",
        osl="tables",
    ),
    Input("hdri_width", "HDRI Width", "INT", 0, "The HDRI's width in texels", osl="hdri_width"),
    Input(
        "env_marginal",
        "Env Marginal Table",
        "STRING",
        "",
        "Environment sampling: the rows' inverse CDF",
        osl="env_marginal",
    ),
    Input(
        "env_conditional",
        "Env Conditional Table",
        "STRING",
        "",
        "Environment sampling: each row's columns' inverse CDF",
        osl="env_conditional",
    ),
    Input(
        "env_pdf_table",
        "Env PDF Table",
        "STRING",
        "",
        "Environment sampling: the density of a draw",
        osl="env_pdf_table",
    ),
    Input(
        "env_samples",
        "Env Samples",
        "INT",
        4,
        "BRDF and environment samples per shading point (each); with the scene transport's "
        "One-Sample Correction, the correction's draws (one technique each)",
        osl="env_samples",
        min=1,
        max=1024,
    ),
    Input(
        "env_visibility",
        "Env Visibility",
        "INT",
        0,
        "Trace environment samples for occlusion",
        osl="env_visibility",
    ),
    Input(
        "one_sample",
        "One-Sample Correction",
        "INT",
        1,
        "The scene transport's correction takes one technique per Env Sample, the world's or "
        "one light's, chosen at random (0: every technique of the world and of each light, as "
        "the lab integrates)",
        osl="one_sample",
    ),
    Input(
        "shadow_rays",
        "Shadow Rays",
        "INT",
        1,
        "Trace shadow rays (0: none, for convex objects that do not shadow each other: the "
        "matrix when its spheres' mutual shadows are off)",
        osl="shadow_rays",
    ),
    Input(
        "seed",
        "Seed",
        "INT",
        0,
        "The render's seed (Cycles' range)",
        osl="seed",
        min=0,
        max=2**31 - 1,
    ),
    Input(
        "normal_derivatives",
        "Normal Derivatives",
        "INT",
        1,
        "1: the Normal input keeps its derivatives (free for the geometry's normal); 0: it "
        "drops them, so the nodes feeding it (a normal map) run without, at about half their "
        "cost under OSL; the same values either way (the add-on sets it from what feeds the "
        "input)",
        osl="normal_derivatives",
    ),
    Input(
        "tex_bottom_up",
        "Texture Rows Bottom-Up",
        "INT",
        0,
        "Whether this Blender's OSL texture() counts rows from the bottom (5.2 and later)",
        osl="tex_bottom_up",
    ),
)

INPUTS = SURFACE + OPTIONS + TRANSPORT + LIGHTING + LIGHTS + OSL_ONLY
GROUP_INPUTS = tuple(i for i in INPUTS if i.group)  # the node group's sockets, in order
OSL_INPUTS = tuple(i for i in INPUTS if i.osl)  # the OSL shader's parameters
BY_KEY = {i.key: i for i in INPUTS}
OPTION_VALUES = {i.key: i.values for i in OPTIONS}  # key -> allowed values

# The node group's outputs (the OSL shader's is its closure, BSDF).
GROUP_OUTPUTS = (("Emission", "SHADER"), ("Value", "RGBA"), ("Residual Albedo", "RGBA"))
OSL_OUTPUT = "BSDF"
# The scene transport's remainder, an OSL output shown as a render pass (an AOV of this name):
# integral of |f_model - f_closure| (n.l) dl, estimated at camera hits (docs/model.md "Light
# transport"); 0 where the closures are the model or in the lab transport.
OSL_RESIDUAL = "residual_albedo"
OSL_OUTPUTS = (OSL_OUTPUT, OSL_RESIDUAL)


@dataclass
class Lighting:
    """What the model node must know of the scene's lights (the OSL shader cannot read other
    objects): the key Sun, the world's HDRI with its strength and rotation, and the files
    derived from the HDRI (importance tables for the reference IBL, the split-sum bake)."""

    sun_to_light: tuple = (0.0, 0.0, 1.0)
    sun_irradiance: tuple = (0.0, 0.0, 0.0)
    hdri: str = ""
    hdri_strength: float = 1.0
    hdri_rotation: float = 0.0  # radians, as the Mapping node's Z
    env_tables: dict = field(default_factory=dict)
    ibl_bake: str = ""
    lights: tuple = ()  # core.lights.Light, in slot order
