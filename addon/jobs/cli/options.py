"""Every option and argument of the command line, declared once: its flag, where argparse
stores it, its type, its default, the values argparse checks and its help; what a command is
(``Command``: its name, help, options and what runs it); and what an option's text means
(a path, a grid, a vector).

A command takes a declared option as it is, or with what differs for it as a parameter at the
place it is used (``OUT.but(help="the job folder")``), so the flag, its destination and its
type cannot drift apart between commands. The parser (cli/parser.py) is assembled from the
commands' options, and so are the command lines the add-on writes (``argv``) and the list of
options that take a value.

The model's switches and their values are core/model/words.py's; their default is the
first value (``ModelOptions``' defaults), which the model checks (its message names the switch). The
limits the command line checks itself (``limits``) are declared here; the others are checked
by what the value sets (core/settings.py, core/model/rules.py, jobs/scene_job.py).
"""

from __future__ import annotations

import dataclasses
import math
import re
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from ..export_job import FORMATS
from ..pipeline import PARITY_HDRIS
from ...blender.renderer import ENGINES
from ...core import model
from ...core.errors import UserError
from ...core.paths import ascii_float, ascii_int, clean
from ...core.settings import MatrixSettings

# what argparse reads a typed value with (their names are in its messages: "invalid
# ascii_int value"); str: the text as it is
_READERS = {int: ascii_int, float: ascii_float, str: str}


@dataclass(frozen=True)
class Option:
    """One option (``--flag``) or positional argument (a bare name) of the command line."""

    flag: str
    help: str
    type: type = str  # str, int, float, or bool: a switch without a value (store_true)
    default: object = None
    dest: str = ""  # where argparse stores it; "": the flag's name ("--sun-dir": sun_dir)
    choices: tuple | None = None  # the values argparse accepts (None: any; checked later)
    required: bool = False
    repeat: bool = False  # may be given more than once (a list of the values)
    limits: tuple | None = None  # (lo, hi) that the command checks (``check``)
    values: tuple | None = None  # a model switch's values (the model checks them)

    def __post_init__(self):
        if not self.dest:
            object.__setattr__(self, "dest", self.flag.lstrip("-").replace("-", "_"))

    @property
    def positional(self) -> bool:
        return not self.flag.startswith("-")

    @property
    def takes_value(self) -> bool:
        return self.type is not bool

    def but(self, **changes) -> Option:
        """This option as a command uses it: the same flag, destination and type, with
        ``changes`` (its default, help, choices, whether it is required)."""
        return dataclasses.replace(self, **changes)

    def add_to(self, parser) -> None:
        kw = {"help": self.help or None}
        if not self.takes_value:
            kw["action"] = "store_true"
        else:
            kw["default"] = self.default
            if self.type is not str:
                kw["type"] = _READERS[self.type]
            if self.choices is not None:
                kw["choices"] = self.choices
            if self.repeat:
                kw["action"] = "append"
            if self.required:
                kw["required"] = True
        if self.positional:
            kw.pop("default", None)
            parser.add_argument(self.flag, **kw)
        else:
            parser.add_argument(self.flag, dest=self.dest, **kw)

    def check(self, value, name: str = ""):
        """``value`` within ``limits``, or a UserError naming it (``name``: the word the
        message uses, the flag by default)."""
        lo, hi = self.limits
        if not lo <= value <= hi:
            raise UserError(f"{name or self.flag} {value} out of range; use {lo} to {hi}")
        return value


@dataclass(frozen=True)
class Command:
    """A subcommand: its name and one-line help, its options in the order its help lists
    them, and the function that runs it with the parsed arguments."""

    name: str
    help: str
    options: tuple
    run: Callable


# ---------------------------------------------------------------------------------------
# The sphere matrix (render, matrix, plan)

# --grid, --size and --samples default by job, filled in after parsing (fill_defaults):
# `plan parity` is the parity job without a --parity on its command line.
JOB_DEFAULTS = {
    "matrix": {"grid": "7x7", "size": 512, "samples": 64},
    "parity": {"grid": "5x3", "size": 384, "samples": 256},
}


def _by_job(dest: str) -> str:
    return f"default {JOB_DEFAULTS['matrix'][dest]}; {JOB_DEFAULTS['parity'][dest]} with --parity"


def fill_defaults(args, job: str) -> None:
    """The defaults of ``job`` ("matrix" or "parity") for what the command line left out."""
    for key, value in JOB_DEFAULTS[job].items():
        if getattr(args, key, None) is None:
            setattr(args, key, value)


def vector_text(values) -> str:
    """A vector as the command line writes it: "1.0,0.766,0.336"."""
    return ",".join(map(str, values))


GRID = Option("--grid", f"ROWSxCOLS of the sphere matrix ({_by_job('grid')})")
SIZE = Option("--size", f"image width and height in pixels ({_by_job('size')})", int)
SAMPLES = Option(
    "--samples",
    f"render samples per pixel ({_by_job('samples')})",
    int,
    limits=(1, model.MAX_SAMPLES),
)
HDRI = Option("--hdri", "equirectangular HDRI (default: Blender's forest.exr)", default="")
HDRI_STRENGTH = Option("--hdri-strength", "the world's strength", float, 1.0)
HDRI_ROTATION = Option("--hdri-rotation", "degrees about Z", float, 0.0)
SUN_DIR = Option(
    "--sun-dir", "X,Y,Z toward the Sun", default=vector_text(MatrixSettings.sun_to_light)
)
SUN_STRENGTH = Option("--sun-strength", "Sun irradiance (W/m^2)", float, 1.0)
LIGHTS = Option(
    "--lights",
    "FILE.json: a list of Blender lights (type, location, rotation_euler, color, energy, "
    "...) in place of the key Sun; Principled is rendered under the same lights "
    '(docs/model.md "Lights")',
    default="",
)
ALBEDO = Option(
    "--albedo", "R,G,B linear albedo (default: gold)", default=vector_text(model.MATRIX_ALBEDO)
)
ALBEDO_TEXTURE = Option(
    "--albedo-texture",
    "FILE: a colour image on every sphere in place of --albedo (sRGB unless the file is "
    'float; docs/usage.md "Textures on the sphere matrix")',
    default="",
)
NORMAL_MAP = Option(
    "--normal-map",
    "FILE: a tangent-space normal map on every sphere (OpenGL convention, green up, as "
    "Blender's Normal Map node reads it)",
    default="",
)
NORMAL_STRENGTH = Option(
    "--normal-strength", "the normal map's strength (Blender's Normal Map node)", float, 1.0
)
TEXTURED = Option(
    "--textured",
    "the shipped texture pair (a brick wall, CC0) as --albedo-texture and --normal-map, "
    "where those are not given",
    bool,
)
IBL = Option(
    "--ibl",
    "indirect light: " + "|".join(model.IBL_MODES) + " (default: reference; split_sum for "
    "the node group; the baked modes use the files of 'ctlab bake', made and cached on "
    "demand; the lab transport's: scene path traces the world)",
)


def _switch(flag: str, values: tuple, note: str = "", dest: str = "") -> Option:
    """A model switch: its values, the first the default (ModelOptions'), checked by the
    model."""
    return Option(flag, "|".join(values) + note, default=values[0], dest=dest, values=values)


G = _switch("--g", model.G_MODELS, dest="g_model")
DIFFUSE = _switch("--diffuse", model.DIFFUSE_MODELS, dest="diffuse_model")
UNITS = _switch("--units", model.UNITS, " (unity: x pi on direct light; lab transport only)")
ENERGY = _switch("--energy", model.ENERGY_MODES, " (compensated: Kulla-Conty multiple scattering)")
# The default transport depends on the command: the sphere matrix, its views and the parity
# job study the model, whose exact values need the lab transport (the rule's default
# in the lab context, core/model/rules.py); `ctlab scene` puts the model on a user's
# objects, where every object and light counts, so it defaults to the scene transport
# (docs/model.md "Light transport"; `scene` says so where it takes the option).
LIGHT_TRANSPORT = _switch(
    "--light-transport",
    model.LIGHT_TRANSPORTS,
    " (lab: the model lights itself, exactly, from the HDRI, the Sun and the lights; scene: "
    "Cycles path traces the model's closures, plus its correction for the world and the "
    "lights)",
).but(default=model.DEFAULT_TRANSPORT[model.LAB])
ENV_SAMPLES = Option(
    "--env-samples",
    "environment samples per shading point and render sample (each of BRDF and "
    "environment sampling; default: "
    + ", ".join(f"{n} with the {t} transport" for t, n in model.DEFAULT_ENV_SAMPLES.items())
    + ")",
    int,
)
ENV_VISIBILITY = Option(
    "--env-visibility", "trace environment samples for occlusion by other objects", bool
)
PRINCIPLED_DISTRIBUTION = Option(
    "--principled-distribution",
    "Principled's GGX",
    default="MULTI_GGX",
    choices=("MULTI_GGX", "GGX"),
)
SEED = Option("--seed", "the render's seed", int, 0)
VERBOSE = Option("--verbose", "show Blender's own output", bool)

MATRIX_OPTIONS = (
    GRID,
    SIZE,
    SAMPLES,
    HDRI,
    HDRI_STRENGTH,
    HDRI_ROTATION,
    SUN_DIR,
    SUN_STRENGTH,
    LIGHTS,
    ALBEDO,
    ALBEDO_TEXTURE,
    NORMAL_MAP,
    NORMAL_STRENGTH,
    TEXTURED,
    IBL,
    G,
    DIFFUSE,
    UNITS,
    ENERGY,
    LIGHT_TRANSPORT,
    ENV_SAMPLES,
    ENV_VISIBILITY,
    PRINCIPLED_DISTRIBUTION,
    SEED,
    VERBOSE,
)

# ---------------------------------------------------------------------------------------
# The other commands' options

OUT = Option("--out", "output folder", required=True)
SHADER = Option(
    "--shader",
    "the implementation that evaluates the model (default osl)",
    default="osl",
    choices=model.IMPLEMENTATIONS,
)
VIEW = Option(
    "--view", "|".join(model.VIEWS) + "|all (all: one sub-folder per view)", default="full"
)
ENGINE = Option(
    "--engine",
    "cycles (CPU; SVM for the node group) or eevee (node group only)",
    default=ENGINES[0],
    choices=ENGINES,
)
PIXEL_CENTRES = Option(
    "--pixel-centres",
    "every view as one sample at each pixel centre, like the term views (exact per-pixel "
    "values, no anti-aliasing; OSL or node group)",
    bool,
)
PARITY = Option(
    "--parity",
    "the Principled-parity check instead: metallic spheres, Smith G, Lambert, reference IBL, "
    "Sun off, against Principled's single-scatter GGX, for each of --parity-hdris (or --hdri)",
    bool,
)
PARITY_HDRIS = Option(
    "--parity-hdris",
    "Blender's bundled HDRIs for --parity (default: %(default)s)",
    default=",".join(PARITY_HDRIS),
)
WORKERS = Option(
    "--workers",
    "render tasks as this many local processes (default 1: in this one)",
    int,
    1,
    limits=(1, 256),
)
JOB = Option(
    "job",
    "matrix (the main job; --parity for the parity job) or parity",
    choices=("matrix", "parity"),
)
OPENJD = Option(
    "--openjd", "also write an Open Job Description bundle, JOB/openjd/template.json", bool
)
FLAMENCO = Option("--flamenco", "also write a Flamenco job type, JOB/flamenco/ctlab-<job>.js", bool)
JOB_DIR = Option("job_dir", "the job folder (plan.json)")
TASK_ID = Option("task_id", "a task id of plan.json")
DIR_A = Option("dir_a", "")
DIR_B = Option("dir_b", "")
HDRI_FILE = Option("hdri", "equirectangular float HDRI (.exr, .hdr)")
METALLIC = Option("--metallic", "0 to 1 (default 0)", float, 0.0)
SMOOTHNESS = Option("--smoothness", "0 to 1 (default 0.5)", float, 0.5)
COMPARE = Option(
    "--compare",
    "overlay a variant: KEY=VALUE with KEY g, diffuse or energy (comma list, repeatable), "
    "e.g. g=smith_ggx_correlated,g=unity_smith_joint",
    repeat=True,
)
BLEND = Option("blend", "the .blend file (opened, never written)")
CONVERT = Option(
    "--convert",
    "the other way: the scene's Principled materials converted to the model, the originals "
    "as the reference",
    bool,
)
CAMERA = Option("--camera", "a camera object (default: the scene's)")
FORMAT = Option("--format", "|".join(FORMATS), choices=FORMATS, required=True)
FORCE = Option(
    "--force",
    "replace files of the same names in --out that ctlab did not write (by default they are "
    "refused and left alone)",
    bool,
)


def per_material(option: Option, word: str) -> Option:
    """A model switch as ``ctlab scene`` takes it: one value for every model material of the
    file, or, left out, each material's own; argparse checks it against the model's values."""
    return option.but(
        default=None,
        choices=option.values,
        help=f"{word} for every model material (default: each material's own)",
    )


# ---------------------------------------------------------------------------------------
# What an option's text means


def check_path(text: str, what: str) -> Path:
    """A path the user typed, through the one path gate (core.paths.clean: absolute,
    normalised, no form Blender reads otherwise, within the byte limits; --out keeps room
    for the names written below it)."""
    return clean(text, what, output=what == "--out")


def parse_vector(text: str, n: int, what: str) -> tuple:
    try:
        values = tuple(ascii_float(x) for x in text.split(","))
    except ValueError:
        values = ()
    if len(values) != n or not all(math.isfinite(v) for v in values):
        raise UserError(f"malformed {what} {text!r}; give {n} comma-separated numbers")
    return values


_DIGITS = re.compile(r"[0-9]+", re.ASCII)  # str.isdigit also takes '²', int() does not


def parse_grid(text: str) -> tuple:
    parts = text.lower().split("x")
    if len(parts) != 2 or not all(_DIGITS.fullmatch(p) for p in parts):
        raise UserError(f"malformed grid {text!r}; give ROWSxCOLS, e.g. 7x7")
    return int(parts[0]), int(parts[1])
