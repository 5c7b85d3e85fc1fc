"""The model's words: the values its switches, views, implementations and light transports
take (docs/model.md "Switches", "Views", "Light transport"), written once. The first value of
a switch is its default (core/model/rules.py applies it). Their names in the UI are
addon/ui/labels.py's.
"""

# --- Implementations: who carries the model, and the reference it is compared with.
# osl: the OSL shader (osl/cook_torrance.osl); nodes: the node group
# (node_groups/cook_torrance.toml); principled: Blender's Principled BSDF, path traced.
IMPLEMENTATIONS = ("osl", "nodes")
REFERENCE = "principled"
SHADERS = IMPLEMENTATIONS + (REFERENCE,)  # what a render of the matrix can use

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

# --- The scene's lights (docs/model.md "Lights"): LIGHT_SLOTS slots, each a Blender light in
# world space, kept in step by drivers and the sync handler (blender/light_sync.py) or set from
# a --lights file (core/lights.py). The key Sun stays a light of its own.
LIGHT_SLOTS = 8
# The Type input: 0 an empty slot, else one of these (an Area light's shape picks 4 or 5).
LIGHT_TYPE_CODES = {"SUN": 1, "POINT": 2, "SPOT": 3, "AREA_RECTANGLE": 4, "AREA_ELLIPSE": 5}

REC709_LUMINANCE = (0.2126, 0.7152, 0.0722)  # Y of linear Rec. 709 RGB
DEFAULT_ALBEDO = (0.8, 0.8, 0.8)
MATRIX_ALBEDO = (1.0, 0.766, 0.336)  # gold: metals show their colour in the matrix
