"""The model's interface, written once (docs/model.md): its surface inputs, switches, views,
the key-light and world inputs, and the derived quantities the UI shows.

Every implementation and caller reads these names from here: the OSL shader's parameters
(tests/render/test_interface.py checks the shader against this table), the node group's interface
(addon/blender/node_group.py builds its sockets from INPUTS), the model-node API, light sync,
the command line and the UI. Like MaterialX's node definitions, one interface serves
implementations in two languages.
"""

from __future__ import annotations

from dataclasses import dataclass, field

# --- Implementations: who carries the model, and the reference it is compared with.
# osl: the OSL shader (osl/cook_torrance.osl); nodes: the node group
# (node_groups/cook_torrance.toml); principled: Blender's Principled BSDF, path traced.
IMPLEMENTATIONS = ("osl", "nodes")
REFERENCE = "principled"
SHADERS = IMPLEMENTATIONS + (REFERENCE,)  # what a render of the matrix can use
IMPLEMENTATION_LABELS = {
    "osl": (
        "OSL Shader",
        "The OSL shader: Cycles on the CPU with Open Shading Language on; "
        "also offers the reference (Monte Carlo) indirect light",
    ),
    "nodes": ("Node Group", "The shader-node group: Cycles (CPU or GPU, SVM or OSL) and EEVEE"),
}
# The renders' names in reports and the comparison operators
SHADER_LABELS = {
    "osl": ("Cook-Torrance (OSL)", "The OSL shader (Cycles on the CPU)"),
    "nodes": ("Cook-Torrance (Node Group)", "The node group (Cycles and EEVEE)"),
    "principled": ("Principled BSDF", "Blender's Principled BSDF, the reference"),
}

# --- Switches (docs/model.md "Switches"); the first value is the default.
# unity_smith_joint: Unity's approximate height-correlated Smith visibility
# (SmithJointGGXVisibilityTerm in UnityStandardBRDF.cginc), BRDF1_Unity_PBS's G
G_MODELS = ("cook_torrance", "smith_ggx_correlated", "unity_smith_joint")
DIFFUSE_MODELS = ("disney", "lambert")
# none: the seed's single-scattering specular; compensated: Kulla and Conty's (2017) lobe for
# the energy that single scattering loses
ENERGY_MODES = ("none", "compensated")
UNITS = ("physical", "unity")
# How the material is lit (docs/model.md "Light transport"). lab: the model computes its own
# light (the world's HDRI, the key Sun, the light slots) and emits it, exactly, as a pixel of a
# view; scene: the model as Cycles closures, path traced with everything in the scene (objects,
# bounces, mesh emitters, any world), plus an emission that corrects the closures to the model
# for the world and the lights (a control variate) where Cycles has no closure for it.
LIGHT_TRANSPORTS = ("lab", "scene")
LIGHT_TRANSPORT_LABELS = {
    "lab": (
        "Lab",
        "The model lights itself from the world's HDRI, the key Sun and the light "
        "slots, exactly (term views, the matrix, parity; the command line's default); "
        "other objects are not seen",
    ),
    "scene": (
        "Scene",
        "Path traced by Cycles: reflects other objects, receives bounce and "
        "mesh-emitter light, any world; exact for the world and the lights (the "
        "default of materials made in the UI)",
    ),
}
# Views the scene transport path traces; every other view is the lab's (a path tracer cannot
# split direct from indirect light inside a material; Cycles' render passes do that).
SCENE_VIEWS = ("full",)
# The closures Cycles has: GGX with Schlick's Fresnel and the height-correlated Smith G, and
# Burley's or Lambert's diffuse; the rest of the model goes through the correction.
SCENE_EXACT_G = "smith_ggx_correlated"
# reference: Monte Carlo against the HDRI (OSL only); split_sum (Karis 2013) and unity
# (Unity's reflection-probe approximation) read the files baked by core.ibl_bake.
IBL_MODES = ("reference", "split_sum", "unity", "split_sum_corrected")
BAKED_IBL_MODES = ("split_sum", "unity", "split_sum_corrected")
# The IBL mode is the lab transport's: the scene transport path traces the world.
LAB_ONLY = " (Lab transport; Scene path traces the world)"
IBL_LABELS = {
    "reference": ("Reference", "Monte Carlo integration against the HDRI" + LAB_ONLY),
    "split_sum": ("Split-Sum", "Pre-filtered levels and the DFG table (baked, cached)" + LAB_ONLY),
    "unity": ("Unity", "Unity's reflection-probe approximation (baked, cached)" + LAB_ONLY),
    "split_sum_corrected": (
        "Split-Sum Corrected",
        "The split-sum toward the lobe's dominant direction "
        "(Lagarde and de Rousiers 2014; baked, cached)" + LAB_ONLY,
    ),
}

# --- Views (docs/model.md "Views"), in this order everywhere (the node group's View index).
LIGHTING_VIEWS = (
    "full",
    "direct",
    "indirect",
    "direct_diffuse",
    "direct_specular",
    "indirect_diffuse",
    "indirect_specular",
)
TERM_VIEWS = (
    "D",
    "F",
    "G",
    "specular_brdf",
    "diffuse_brdf",
    "NdotL",
    "NdotV",
    "NdotH",
    "VdotH",
    "normal",
    "albedo",
    "spec_color",
)
VIEWS = LIGHTING_VIEWS + TERM_VIEWS
# Rendered with one sample at each pixel centre (one exact shading point a pixel).
EXACT_VIEWS = TERM_VIEWS
# Their PNG uses Blender's AgX view transform; the term views use Standard (raw values).
AGX_VIEWS = LIGHTING_VIEWS

# The switches' and views' names in the UI (a value not listed is its name, title-cased).
OPTION_LABELS = {
    "cook_torrance": "Cook-Torrance",
    "smith_ggx_correlated": "Smith (height-correlated)",
    "unity_smith_joint": "Unity (Smith joint approximation)",
    "disney": "Disney",
    "lambert": "Lambert",
    "physical": "Physical",
    "unity": "Unity",
    "none": "Single Scattering",
    "compensated": "Compensated",
    "NdotL": "N·L",
    "NdotV": "N·V",
    "NdotH": "N·H",
    "VdotH": "V·H",
    "D": "D",
    "F": "F",
    "G": "G",
    "spec_color": "Specular Colour",
    "specular_brdf": "Specular BRDF",
    "diffuse_brdf": "Diffuse BRDF",
}


def label(value: str) -> str:
    """A switch's or a view's name in the UI."""
    return (
        OPTION_LABELS.get(value)
        or IBL_LABELS.get(value, (None,))[0]
        or LIGHT_TRANSPORT_LABELS.get(value, (None,))[0]
        or value.replace("_", " ").title()
    )


REC709_LUMINANCE = (0.2126, 0.7152, 0.0722)  # Y of linear Rec. 709 RGB
MIN_ALPHA = 0.002  # GGX alpha = max(pr^2, MIN_ALPHA)
DEFAULT_ALBEDO = (0.8, 0.8, 0.8)
MATRIX_ALBEDO = (1.0, 0.766, 0.336)  # gold: metals show their colour in the matrix


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

# --- The scene's lights (docs/model.md "Lights"): LIGHT_SLOTS slots, each a Blender light in
# world space, kept in step by drivers and the sync handler (blender/light_sync.py) or set from
# a --lights file (core/lights.py). The key Sun above stays a light of its own.
LIGHT_SLOTS = 8
# The Type input: 0 an empty slot, else one of these (an Area light's shape picks 4 or 5).
LIGHT_TYPE_CODES = {"SUN": 1, "POINT": 2, "SPOT": 3, "AREA_RECTANGLE": 4, "AREA_ELLIPSE": 5}


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
        "BRDF and environment samples per shading point (each)",
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
        "tex_bottom_up",
        "Texture Rows Bottom-Up",
        "INT",
        0,
        "Whether this Blender's OSL texture() counts rows from the bottom (5.2 and later)",
        osl="tex_bottom_up",
    ),
)

INPUTS = SURFACE + OPTIONS + LIGHTING + LIGHTS + OSL_ONLY
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


# --- Derived quantities (docs/model.md; Unity's UnityStandardUtils / UnityStandardBRDF)


def clamp01(x: float) -> float:
    """Inputs outside their range are clamped, never passed on."""
    return min(1.0, max(0.0, float(x)))


def perceptual_roughness(smoothness: float) -> float:
    """Unity's SmoothnessToPerceptualRoughness: pr = 1 - smoothness."""
    return 1.0 - clamp01(smoothness)


def ggx_alpha(smoothness: float) -> float:
    """GGX alpha = max(pr^2, 0.002) (Unity's PerceptualRoughnessToRoughness, clamped)."""
    return max(perceptual_roughness(smoothness) ** 2, MIN_ALPHA)


class ModelOptions:
    """The model node's settings other than its surface inputs: the view, the switches and
    the reference integrator's settings."""

    def __init__(
        self,
        view="full",
        g_model=G_MODELS[0],
        diffuse_model=DIFFUSE_MODELS[0],
        units=UNITS[0],
        energy=ENERGY_MODES[0],
        ibl=IBL_MODES[0],
        env_samples=4,
        env_visibility=False,
        sun_shadow=True,
        shadow_rays=True,
        seed=0,
        light_transport=LIGHT_TRANSPORTS[0],
    ):
        self.view = view
        self.g_model = g_model
        self.diffuse_model = diffuse_model
        self.units = units
        self.energy = energy
        self.ibl = ibl
        self.env_samples = int(env_samples)
        self.env_visibility = bool(env_visibility)
        self.sun_shadow = bool(sun_shadow)
        self.shadow_rays = bool(shadow_rays)
        self.seed = int(seed)
        self.light_transport = light_transport
        self.validate()

    def validate(self):
        from .errors import UserError

        for i in OPTIONS:
            value = getattr(self, i.key)
            if value not in i.values:
                what = i.label if i.key in ("g_model", "ibl") else i.label.lower()
                raise UserError(f"unknown {what} {value!r}; choose one of: {', '.join(i.values)}")
        for key in ("env_samples", "seed"):
            lo, hi, value = int(BY_KEY[key].min), int(BY_KEY[key].max), getattr(self, key)
            if not lo <= value <= hi:
                raise UserError(f"{key.replace('_', ' ')} {value} out of range; use {lo} to {hi}")
        problem = scene_transport_problem(self)
        if problem:
            raise UserError(problem)

    def path_traced(self) -> bool:
        """Whether Cycles path traces the material (the scene transport's full view)."""
        return self.light_transport == "scene" and self.view in SCENE_VIEWS

    def as_dict(self):
        return dict(vars(self))


def scene_transport_problem(options) -> str | None:
    """Why these options cannot use the scene transport, or None. Unity's units scale direct
    light by pi, which no closure does: they are lab-only (docs/model.md "Light
    transport"). The IBL mode stays a lab setting: the scene transport path traces the world
    (its correction integrates the HDRI as the reference IBL does)."""
    if options.light_transport != "scene":
        return None
    if options.units != UNITS[0]:
        return (
            "Unity's units (x pi on direct light) exist in the lab transport only; use "
            "--units physical with --light-transport scene"
        )
    return None


def indirect_light(impl: str, ibl: str | None = None) -> str:
    """The indirect-light mode ``impl`` renders for a requested one (None: its default). The
    OSL shader has every mode and defaults to the reference integration; the node group has
    the baked modes only and takes the split-sum for the reference."""
    if impl == "nodes" and (ibl is None or ibl not in BAKED_IBL_MODES):
        return BAKED_IBL_MODES[0]
    return ibl or IBL_MODES[0]


def files_needed(impl: str, ibl: str, light_transport: str) -> frozenset:
    """What a model node reads besides the HDRI: "tables" (the environment importance
    tables: the OSL reference integration, and the OSL scene transport's correction of the
    world) and "bake" (the split-sum files: the baked modes). Principled BSDF needs neither."""
    if impl not in IMPLEMENTATIONS:
        return frozenset()
    need = set()
    if impl == "osl" and (ibl == "reference" or light_transport == "scene"):
        need.add("tables")
    if ibl in BAKED_IBL_MODES:
        need.add("bake")
    return frozenset(need)


def scene_residual(g_model: str, energy: str) -> bool:
    """Whether the scene transport needs its correction emission: the closures are the model
    itself for the height-correlated Smith G without energy compensation (Burley's and
    Lambert's diffuse both have a closure)."""
    return g_model != SCENE_EXACT_G or energy != ENERGY_MODES[0]


def transport_notes(
    impl: str,
    light_transport: str,
    view: str,
    units: str,
    g_model: str,
    diffuse_model: str,
    energy: str,
) -> list:
    """What the material sees in its light transport, in words, for the material panel
    (docs/model.md "Light transport"); ``impl`` "osl" or "nodes"."""
    if light_transport == "lab":
        return [
            "Lab: lit by the world's HDRI, the key Sun and the light slots, computed by "
            "the model itself and shown as emission (exact).",
            "It does not see other objects, bounce light or mesh emitters.",
            "Term views and Unity units need Lab: a term view is a BRDF value, not light, "
            "and Unity's pi on direct light has no closure.",
            "New materials made in the UI use Scene.",
        ]
    notes = [
        "Scene: path traced by Cycles like any material: reflects other objects, gets "
        "bounce light, mesh emitters, every light and any world (the UI's default)."
    ]
    if view not in SCENE_VIEWS:
        notes.append(
            f"The view {view!r} is the lab's: a term view is a BRDF value, not light, "
            "and a path tracer cannot split direct from indirect inside a material "
            "(Cycles' render passes do)."
        )
    if units != UNITS[0]:
        notes.append(
            "Unity units exist in Lab only (pi on direct light has no closure): "
            "this material renders in Lab."
        )
    exact = g_model == SCENE_EXACT_G and energy == ENERGY_MODES[0]
    if impl == "osl":
        if exact:
            notes.append(
                "Exact: Cycles' closures are this model (GGX, Schlick, Smith G, "
                f"{'Lambert' if diffuse_model == 'lambert' else 'Burley'} diffuse)."
            )
        else:
            notes.append(
                "Exact for the world's HDRI and the lights (a correction emission); "
                "light from other objects sees Smith's G without compensation."
            )
    else:
        parts = [
            p
            for p, on in (
                ("the G", g_model != SCENE_EXACT_G),
                ("Disney diffuse", diffuse_model != "lambert"),
                ("compensation", energy != ENERGY_MODES[0]),
            )
            if on
        ]
        notes.append(
            "Node group: Metallic BSDF + Diffuse BSDF"
            + (
                f" plus a correction emission for {', '.join(parts)}: exact for the lights, a "
                "split-sum for the world; light from other objects sees Smith's G and Lambert."
                if parts
                else ": exactly this model."
            )
        )
        notes.append("EEVEE lights these closures approximately (probes, screen tracing).")
    return notes


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
