"""The model's rules, written once: the defaults and fallbacks every caller asks for
(docs/model.md "Switches", "Light transport"), and the validation of a node's options.

- The default light transport per context (``resolve``, ``DEFAULT_TRANSPORT``): ``lab`` for
  the lab's jobs (the sphere matrix, parity, term views, plots: the model computed exactly);
  ``scene`` for an artist's material (made in the UI, converted from Principled, compared by
  the scene job: path traced like any material).
- Unity's units exist in the lab transport only (``scene_transport_problem``, one message).
- The indirect light an implementation renders (``indirect_light``): the node group has the
  baked modes only and takes the split-sum for the reference.
- The samples per pixel a render may ask for (``MAX_SAMPLES``).
- The reference integrator's samples per shading point per light transport
  (``DEFAULT_ENV_SAMPLES``).

The UI's EnumProperty defaults, the command line, the scene job and conversion read these;
tests/unit/test_model_rules.py checks that no caller writes its own.
"""

from __future__ import annotations

from ..errors import UserError
from .interface import BY_KEY, OPTIONS
from .words import (
    BAKED_IBL_MODES,
    DIFFUSE_MODELS,
    ENERGY_MODES,
    G_MODELS,
    IBL_MODES,
    IMPLEMENTATIONS,
    LIGHT_TRANSPORTS,
    SCENE_EXACT_G,
    SCENE_VIEWS,
    UNITS,
)

# The contexts a model node is made in: the lab's (the matrix, parity, term views, plots) and
# an artist's (a material made in the UI, converted from Principled, the scene job's).
LAB, ARTIST = "lab", "artist"
CONTEXTS = (LAB, ARTIST)
DEFAULT_TRANSPORT = {LAB: LIGHT_TRANSPORTS[0], ARTIST: LIGHT_TRANSPORTS[1]}
# Samples per pixel: Cycles' own limit, the UI's and the command line's.
MAX_SAMPLES = 65536
# The OSL shader's samples per shading point (each of BRDF and environment sampling) where
# nothing asks for others, per light transport. In the lab they estimate the whole indirect
# light: 4 reach Principled's error soonest (docs/testing.md, "Equal error"). In the scene
# transport they estimate only the correction inside Cycles' path tracing, whose own samples
# carry the noise: 1 gives the same error as 4 in about half the render time
# (docs/testing.md, "Every material of a product shot converted").
DEFAULT_ENV_SAMPLES = {LIGHT_TRANSPORTS[0]: 4, LIGHT_TRANSPORTS[1]: 1}
SCENE_UNITS_PROBLEM = (
    "Unity's units (x pi on direct light) exist in the lab transport only; use "
    "--units physical with --light-transport scene, or the lab transport"
)


def resolve(implementation: str, options: dict | None = None, context: str = LAB) -> dict:
    """The options a model node of ``implementation`` gets for ``options`` (key -> value;
    missing or None: the rule's): the light transport of ``context`` (``DEFAULT_TRANSPORT``),
    the indirect light the implementation renders (``indirect_light``: split-sum on the node
    group), the OSL shader's samples per shading point for that transport
    (``DEFAULT_ENV_SAMPLES``), and Unity's units refused in the scene transport (UserError).
    Options not given stay unset (a caller keeps what a node has)."""
    if context not in CONTEXTS:
        raise ValueError(f"unknown context {context!r}")
    out = {k: v for k, v in (options or {}).items() if v is not None}
    out.setdefault("light_transport", DEFAULT_TRANSPORT[context])
    if implementation in IMPLEMENTATIONS:
        out["ibl"] = indirect_light(implementation, out.get("ibl"))
    if implementation == "osl":
        out.setdefault("env_samples", default_env_samples(out["light_transport"]))
    problem = scene_transport_problem(out.get("units", UNITS[0]), out["light_transport"])
    if problem:
        raise UserError(problem)
    return out


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
        env_samples=None,
        env_visibility=False,
        one_sample=True,
        sun_shadow=True,
        shadow_rays=True,
        seed=0,
        light_transport=DEFAULT_TRANSPORT[LAB],
    ):
        self.view = view
        self.g_model = g_model
        self.diffuse_model = diffuse_model
        self.units = units
        self.energy = energy
        self.ibl = ibl
        if env_samples is None:  # the transport's (an unknown transport: validate says so)
            env_samples = default_env_samples(light_transport)
        self.env_samples = int(env_samples)
        self.env_visibility = bool(env_visibility)
        self.one_sample = bool(one_sample)
        self.sun_shadow = bool(sun_shadow)
        self.shadow_rays = bool(shadow_rays)
        self.seed = int(seed)
        self.light_transport = light_transport
        self.validate()

    def validate(self):
        for i in OPTIONS:
            value = getattr(self, i.key)
            if value not in i.values:
                what = i.label if i.key in ("g_model", "ibl") else i.label.lower()
                raise UserError(f"unknown {what} {value!r}; choose one of: {', '.join(i.values)}")
        for key in ("env_samples", "seed"):
            lo, hi, value = int(BY_KEY[key].min), int(BY_KEY[key].max), getattr(self, key)
            if not lo <= value <= hi:
                raise UserError(f"{key.replace('_', ' ')} {value} out of range; use {lo} to {hi}")
        problem = scene_transport_problem(self.units, self.light_transport)
        if problem:
            raise UserError(problem)

    def path_traced(self) -> bool:
        """Whether Cycles path traces the material (the scene transport's full view)."""
        return self.light_transport == "scene" and self.view in SCENE_VIEWS

    def as_dict(self):
        return dict(vars(self))


def scene_transport_problem(units: str, light_transport: str) -> str | None:
    """Why ``units`` cannot use ``light_transport``, or None: the one rule and its one message.
    Unity's units scale direct light by pi, which no closure does: they are lab-only
    (docs/model.md "Light transport"). The shader and the node group fall back to the lab for
    a material set so in the UI (osl/cook_torrance.osl ``path_traced``, the TOML's ``on``);
    a job refuses. The IBL mode stays a lab setting: the scene transport path traces the world
    (its correction integrates the HDRI as the reference IBL does)."""
    if light_transport == "scene" and units != UNITS[0]:
        return SCENE_UNITS_PROBLEM
    return None


def default_env_samples(light_transport: str) -> int:
    """The OSL shader's samples per shading point for ``light_transport`` where nothing asks
    for others (``DEFAULT_ENV_SAMPLES``; the lab's for a transport it does not know)."""
    return DEFAULT_ENV_SAMPLES.get(light_transport, DEFAULT_ENV_SAMPLES[LIGHT_TRANSPORTS[0]])


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
