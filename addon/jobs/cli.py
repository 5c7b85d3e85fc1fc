"""The command line: ``render``, ``compare``, ``bake``, ``matrix``, ``plot``, ``scene``,
``export`` (jobs/export_job.py), and
the batch jobs as task graphs: ``plan``, ``task``, ``merge`` (jobs/graph.py); scripts/ctlab.py
is the entry. It maps arguments onto settings (core.settings) and runs the pipeline
(jobs/pipeline.py; ``scene``: jobs/scene_job.py).

Bad input gets a one-line message naming the problem and exit status 2, and nothing is
written. Blender's own per-tile output goes to a log file in the system temp folder; the
command prints its own progress, or, with $CTLAB_JSON_EVENTS set (the background job), one
JSON object per event. A job stops between steps when the file named by $CTLAB_CANCEL_FILE
exists (exit status 130; finished outputs are kept).

The scene options are one table (SCENE_ARGS) from which the parser is built and from which
``argv`` writes a command line, so a caller that builds one (the add-on's background
comparison) cannot drift from what the parser reads.
"""

from __future__ import annotations

import argparse
import json
import functools
import math
import os
import re
import sys
import time
from dataclasses import dataclass
from pathlib import Path

from . import pipeline
from ..blender.renderer import ENGINES
from ..core.errors import Cancelled, UserError
from ..core.paths import ascii_float, ascii_int, clean, input_file, safe_name
from ..core.model import (
    DEFAULT_ALBEDO,
    DIFFUSE_MODELS,
    ENERGY_MODES,
    G_MODELS,
    IBL_MODES,
    IMPLEMENTATIONS,
    LIGHT_TRANSPORTS,
    MATRIX_ALBEDO,
    SHADERS,
    UNITS,
    VIEWS,
    ModelOptions,
    indirect_light,
)
from ..core.settings import MatrixSettings

EXIT_BAD_INPUT = 2
EXIT_CANCELLED = 130


class Parser(argparse.ArgumentParser):
    """argparse with its errors on one line (``ctlab: error: ...``, exit status 2) instead of
    the usage text."""

    def error(self, message):
        raise UserError(message)


# A value that starts with "-" and is a number or a list of numbers ("-0.45,-0.55,0.7",
# "-1e-05", "-inf"): argparse would take it for an option.
_NEGATIVE_VALUE = re.compile(r"^-(\d|\.\d|inf|nan)", re.I)


def join_negative_values(argv: list, value_flags) -> list:
    """``--flag -0.5,...`` -> ``--flag=-0.5,...`` for the options that take a value."""
    out, i = [], 0
    while i < len(argv):
        a = str(argv[i])
        if a in value_flags and i + 1 < len(argv) and _NEGATIVE_VALUE.match(str(argv[i + 1])):
            out.append(f"{a}={argv[i + 1]}")
            i += 2
            continue
        out.append(a)
        i += 1
    return out


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


# ---------------------------------------------------------------------------------------
# Output: human lines, or JSON events for the background job


def _json_events() -> bool:
    return bool(os.environ.get("CTLAB_JSON_EVENTS"))


def say(message: str) -> None:
    if _json_events():
        print(json.dumps({"event": "note", "message": message}), flush=True)
    else:
        print(f"[ctlab {time.strftime('%H:%M:%S')}] {message}", flush=True)


def warn(message: str) -> None:
    print(f"ctlab: warning: {message}", file=sys.stderr, flush=True)


def _progress(step: int, total: int, message: str) -> None:
    if _json_events():
        print(
            json.dumps({"event": "progress", "step": step, "total": total, "message": message}),
            flush=True,
        )
    else:
        say(f"[{step}/{total}] {message}")


def _cancel_requested() -> bool:
    flag = os.environ.get("CTLAB_CANCEL_FILE")
    return bool(flag) and os.path.exists(flag)


def events() -> pipeline.Events:
    return pipeline.Events(
        progress=_progress, note=lambda m: say(f"  {m}"), cancelled=_cancel_requested, warn=warn
    )


# ---------------------------------------------------------------------------------------
# The scene options: one table for the parser and for command lines built by callers


@dataclass(frozen=True)
class Arg:
    flag: str
    dest: str
    help: str
    type: object = str
    default: object = None
    choices: tuple | None = None
    flag_only: bool = False  # a switch without a value (store_true)


SCENE_ARGS = (
    Arg("--grid", "grid", "ROWSxCOLS of the sphere matrix (default 7x7; 5x3 with --parity)"),
    Arg("--size", "size", "image width and height in pixels (default 512; 384 with --parity)", int),
    Arg("--samples", "samples", "render samples per pixel (default 64; 256 with --parity)", int),
    Arg("--hdri", "hdri", "equirectangular HDRI (default: Blender's forest.exr)", str, ""),
    Arg("--hdri-strength", "hdri_strength", "the world's strength", float, 1.0),
    Arg("--hdri-rotation", "hdri_rotation", "degrees about Z", float, 0.0),
    Arg(
        "--sun-dir",
        "sun_dir",
        "X,Y,Z toward the Sun",
        str,
        ",".join(map(str, MatrixSettings.sun_to_light)),
    ),
    Arg("--sun-strength", "sun_strength", "Sun irradiance (W/m^2)", float, 1.0),
    Arg(
        "--lights",
        "lights",
        "FILE.json: a list of Blender lights (type, location, "
        "rotation_euler, color, energy, ...) in place of the key Sun; Principled is rendered "
        "under the same lights (docs/model.md \"Lights\")",
        str,
        "",
    ),
    Arg(
        "--albedo",
        "albedo",
        "R,G,B linear albedo (default: gold)",
        str,
        ",".join(map(str, MATRIX_ALBEDO)),
    ),
    Arg(
        "--ibl",
        "ibl",
        "indirect light: " + "|".join(IBL_MODES) + " (default: reference; "
        "split_sum for the node group; the baked modes use the files of 'ctlab bake', made and "
        "cached on demand; the lab transport's: scene path traces the world)",
    ),
    Arg("--g", "g_model", "|".join(G_MODELS), str, G_MODELS[0]),
    Arg("--diffuse", "diffuse_model", "|".join(DIFFUSE_MODELS), str, DIFFUSE_MODELS[0]),
    Arg(
        "--units",
        "units",
        "|".join(UNITS) + " (unity: x pi on direct light; lab transport only)",
        str,
        UNITS[0],
    ),
    Arg(
        "--energy",
        "energy",
        "|".join(ENERGY_MODES) + " (compensated: Kulla-Conty multiple scattering)",
        str,
        ENERGY_MODES[0],
    ),
    Arg(
        "--light-transport",
        "light_transport",
        "|".join(LIGHT_TRANSPORTS) + " (lab: the "
        "model lights itself, exactly, from the HDRI, the Sun and the lights; scene: Cycles "
        "path traces the model's closures, plus its correction for the world and the lights)",
        str,
        LIGHT_TRANSPORTS[0],
    ),
    Arg(
        "--env-samples",
        "env_samples",
        "environment samples per shading point and render "
        "sample (each of BRDF and environment sampling)",
        int,
        4,
    ),
    Arg(
        "--env-visibility",
        "env_visibility",
        "trace environment samples for occlusion by other objects",
        flag_only=True,
    ),
    Arg(
        "--principled-distribution",
        "principled_distribution",
        "Principled's GGX",
        str,
        "MULTI_GGX",
        ("MULTI_GGX", "GGX"),
    ),
    Arg("--seed", "seed", "the render's seed", int, 0),
    Arg("--verbose", "verbose", "show Blender's own output", flag_only=True),
)
_BY_DEST = {a.dest: a for a in SCENE_ARGS}


def add_scene_arguments(p: argparse.ArgumentParser) -> None:
    for a in SCENE_ARGS:
        if a.flag_only:
            p.add_argument(a.flag, dest=a.dest, action="store_true", help=a.help)
        else:
            p.add_argument(
                a.flag,
                dest=a.dest,
                default=a.default,
                type={int: ascii_int, float: ascii_float}.get(a.type, a.type),
                choices=a.choices,
                help=a.help,
            )


@functools.cache
def _flags(command: str) -> dict:
    """dest -> (its long option, whether it is a flag without a value), of a subcommand's
    parser: the one table command lines are written from."""
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction)).choices[
        command
    ]
    return {
        a.dest: (max(a.option_strings, key=len), a.nargs == 0)
        for a in sub._actions
        if a.option_strings and a.dest != "help"
    }


def argv(command: str, *words, **values) -> list:
    """A command line for ``command`` with options given by their destination names, read
    from the parser itself (``argv("matrix", "--out", OUT, sun_dir=(x, y, z), samples=64)``,
    ``argv("plot", out=OUT, g_model="cook_torrance")``). Values are written as
    ``--flag=value``, so a negative number or a list starting with "-" cannot be read as an
    option; an unknown name is a KeyError here rather than a parse error in the child."""
    out = [command, *map(str, words)]
    flags = _flags(command)
    for dest, value in values.items():
        flag, flag_only = flags[dest]
        if flag_only:
            if value:
                out.append(flag)
            continue
        if isinstance(value, (tuple, list)):
            value = ",".join(f"{float(v):.9g}" for v in value)
        elif isinstance(value, float):
            value = f"{value:.9g}"
        out.append(f"{flag}={value}")
    return out


FLOAT32_MAX = 3.4028234663852886e38
DEFAULTS = {"grid": "7x7", "size": 512, "samples": 64}
PARITY_DEFAULTS = {"grid": "5x3", "size": 384, "samples": 256}


def settings_from(args, shader: str, view: str) -> MatrixSettings:
    """The scene and model settings from the command line, validated."""
    if view not in VIEWS and view != "all":
        raise UserError(f"unknown view {view!r}; choose one of: {', '.join(VIEWS)}")
    rows, cols = parse_grid(args.grid)
    if args.samples < 1 or args.samples > 65536:
        raise UserError(f"samples {args.samples} out of range; use 1 to 65536")
    ibl = args.ibl or indirect_light(shader)
    # degrees on the command line, radians inside (the Mapping node's unit)
    if not (math.isfinite(args.hdri_rotation) and abs(args.hdri_rotation) <= FLOAT32_MAX):
        raise UserError(
            f"hdri rotation {args.hdri_rotation} out of range; use a finite number of degrees"
        )
    model = ModelOptions(
        view=view,
        g_model=args.g_model,
        diffuse_model=args.diffuse_model,
        units=args.units,
        energy=args.energy,
        ibl=ibl,
        env_samples=args.env_samples,
        env_visibility=args.env_visibility,
        seed=args.seed,
        light_transport=args.light_transport,
    )
    hdri = (
        str(
            input_file(
                args.hdri,
                "HDRI",
                missing=f"HDRI not found: {args.hdri} (give an "
                "existing equirectangular .exr or .hdr file)",
            )
        )
        if args.hdri
        else ""
    )
    s = MatrixSettings(
        rows=rows,
        cols=cols,
        hdri=hdri,
        hdri_strength=args.hdri_strength,
        hdri_rotation=math.radians(args.hdri_rotation),
        sun_to_light=parse_vector(args.sun_dir, 3, "sun direction"),
        sun_strength=args.sun_strength,
        albedo=parse_vector(args.albedo, 3, "albedo"),
        shader=shader,
        principled_distribution=args.principled_distribution,
        width=args.size,
        height=args.size,
        model=model,
        **lights_from(args),
    )
    return s


def lights_from(args) -> dict:
    """The --lights file's lights, read and checked (one clear line for a bad file)."""
    if not args.lights:
        return {}
    from ..core.lights import read_lights

    path = input_file(args.lights, "--lights", missing=f"lights file {args.lights} not found")
    return {"lights": tuple(read_lights(path)), "lights_file": str(path)}


# ---------------------------------------------------------------------------------------
# The commands


def cmd_render(args) -> None:
    views = VIEWS if args.view == "all" else (args.view,)
    if args.engine == "eevee" and args.shader != "nodes":
        raise UserError("--engine eevee renders the node group only; add --shader nodes")
    settings = settings_from(args, args.shader, views[0])
    if args.pixel_centres and args.light_transport == "scene":
        raise UserError(
            "--pixel-centres renders one sample at each pixel centre; the scene "
            "transport is path traced: use --light-transport lab"
        )
    from ..blender.paths import resolve_hdri
    from ..core.hdri import load_hdri

    load_hdri(resolve_hdri(settings.hdri))
    out = check_path(args.out, "--out")
    dirs = {v: out / v for v in views} if args.view == "all" else {views[0]: out}
    say(
        f"rendering {settings.shader} view={args.view} grid={args.grid} size={args.size} "
        f"samples={args.samples} -> {out}"
    )

    def report(i, view, d):
        _progress(i + 1, len(dirs), f"{view}: {d['render_seconds']:.1f} s -> {dirs[view]}")

    pipeline.render_views(
        settings,
        dirs,
        args.samples,
        pixel_centres=args.pixel_centres,
        engine=args.engine,
        verbose=args.verbose,
        events=events(),
        on_view=report,
    )
    say("done: render.exr, render.png and scene.json in each folder")


def cmd_compare(args) -> None:
    from ..core.compare import compare

    out = check_path(args.out, "--out")
    result = compare(
        check_path(args.dir_a, "first render folder"),
        check_path(args.dir_b, "second render folder"),
        out,
    )
    o = result["overall"]
    psnr = "identical images" if o["psnr_db"] is None else f"PSNR {o['psnr_db']:.2f} dB"
    say(
        f"compared {len(result['cells'])} cells: mean CIEDE2000 {o['ciede2000_mean']:.2f}, "
        f"{psnr} -> {out / 'metrics.json'}, diff.png"
    )


def cmd_bake(args) -> None:
    """Bake the split-sum files of an HDRI (cached by content hash), optionally copied to --out."""
    hdri = check_path(args.hdri, "HDRI")
    out = None if args.out is None else check_path(args.out, "--out")
    say(f"baking {hdri}")
    folder = pipeline.run_bake(hdri, out, events(), warn)
    names = ", ".join(sorted(p.name for p in folder.iterdir() if not p.name.startswith(".")))
    say(f"done: {folder}: {names}")


def job_inputs(args) -> tuple:
    """("matrix" or "parity", base settings, the parity job's HDRIs and name) from the
    matrix options, validated."""
    base = settings_from(args, "osl", "full")
    if not args.parity:
        return "matrix", base, {}
    if base.lights:  # one run under the lights, with --hdri or the first parity HDRI
        hdris = [Path(base.hdri)] if args.hdri else pipeline.parity_hdris(args.parity_hdris)[:1]
        name = safe_name(Path(base.lights_file).stem, "lights")  # never "..": stays in --out
    else:
        hdris = [Path(base.hdri)] if args.hdri else pipeline.parity_hdris(args.parity_hdris)
        name = None
    return "parity", base, {"hdris": hdris, "name": name}


def check_workers(args) -> int:
    workers = getattr(args, "workers", 1)
    if not 1 <= workers <= 256:
        raise UserError(f"--workers {workers} out of range; use 1 to 256")
    return workers


def say_done(result: dict) -> None:
    """The last line of a matrix or parity job (run here, or merged from its tasks)."""
    if result.get("job") == "parity":
        say(
            f"done: parity {'holds' if result['holds'] else 'FAILS'} (every sphere's mean "
            f"CIEDE2000 <= {pipeline.PARITY_BOUND}); open {result['report']}"
        )
        return
    de = {k: r["overall"]["ciede2000_mean"] for k, r in result["comparisons"].items()}
    psnr = result["comparisons"]["compare"]["overall"]["psnr_db"]
    say(
        f"done: mean CIEDE2000 against Principled {de['compare']:.2f} "
        f"(PSNR {'-' if psnr is None else f'{psnr:.2f}'} dB); split-sum "
        f"against the reference {de['compare_split_sum']:.2f} (corrected "
        f"{de['compare_split_sum_corrected']:.2f}), Unity {de['compare_unity']:.2f}; "
        f"node group against OSL {de['compare_nodes']:.3f}; open {result['report']}"
    )


def cmd_matrix(args) -> None:
    """The main job (or, with --parity, the Principled-parity check)."""
    if args.parity:
        return cmd_parity(args)
    workers = check_workers(args)
    _, base, _ = job_inputs(args)
    out = check_path("out/matrix" if args.out is None else args.out, "--out")
    from . import graph

    result = graph.run_matrix(base, args.samples, out, events(), args.verbose, workers)
    say_done(dict(result, job="matrix"))


def cmd_parity(args) -> None:
    """The Principled-parity check (graph.run_parity) for each HDRI of --parity-hdris, or
    for --hdri."""
    workers = check_workers(args)
    _, base, extra = job_inputs(args)
    out = check_path("out/parity" if args.out is None else args.out, "--out")
    from . import graph

    result = graph.run_parity(
        base,
        extra["hdris"],
        args.samples,
        out,
        events(),
        args.verbose,
        name=extra["name"],
        workers=workers,
    )
    say_done(dict(result, job="parity"))


def cmd_plan(args) -> None:
    """``ctlab plan matrix [options] --out JOB``: the job's task graph (jobs/graph.py)."""
    from . import graph

    if args.job == "parity":
        args.parity = True
    fill_defaults(args, PARITY_DEFAULTS if args.parity else DEFAULTS)
    job, base, extra = job_inputs(args)
    out = check_path(args.out, "--out")
    plan = graph.make_plan(job, base, args.samples, **extra)
    graph.write_plan(out, plan, openjd=args.openjd, flamenco=args.flamenco)
    renders = [t for t in plan["tasks"] if t["kind"] == "render"]
    say(
        f"planned the {job} job: {len(renders)} render tasks and a merge -> "
        f"{out / 'plan.json'}"
        + (f", {out / 'openjd' / 'template.json'}" if args.openjd else "")
        + (f", {out / 'flamenco' / f'ctlab-{job}.js'}" if args.flamenco else "")
    )
    for t in plan["tasks"]:
        say(
            f"  {t['id']}  {t['kind']}"
            + (
                f"  {t['folder']}"
                if t["kind"] == "render"
                else f"  after {len(t['depends'])} tasks"
            )
        )


def cmd_task(args) -> None:
    """``ctlab task JOB ID``: one task of a plan (a finished one does nothing)."""
    from . import graph

    job = Path(os.path.normpath(check_path(args.job_dir, "job folder")))
    result = graph.run_task(job, args.task_id, events(), args.verbose)
    if result["ran"] and "scene" in result:
        say(f"done: task {args.task_id} in {result['seconds']:.1f} s")


def cmd_merge(args) -> None:
    """``ctlab merge JOB``: the comparisons, plots and report from the job folder."""
    from . import graph

    job = Path(os.path.normpath(check_path(args.job_dir, "job folder")))
    say_done(graph.merge(job, events(), args.verbose))


def plot_settings_from(args):
    """The plot's settings from the command line, validated (core.brdf_plot.PlotSettings)."""
    from ..core.brdf_plot import PlotSettings, parse_compare

    views = [v.strip() for item in (args.view or ()) for v in item.split(",") if v.strip()]
    return PlotSettings(
        metallic=args.metallic,
        smoothness=args.smoothness,
        albedo=parse_vector(args.albedo, 3, "albedo"),
        g_model=args.g_model,
        diffuse_model=args.diffuse_model,
        units=args.units,
        energy=args.energy,
        shader=args.shader,
        views=tuple(views),
        compare=parse_compare(args.compare),
    )


def cmd_plot(args) -> None:
    """The BRDF plotted from the model's own code (pipeline.run_plot)."""
    settings = plot_settings_from(args)
    out = check_path(args.out, "--out")
    say(
        f"plotting the {settings.shader} model: metallic {settings.metallic:g}, smoothness "
        f"{settings.smoothness:g} -> {out}"
    )
    data = pipeline.run_plot(settings, out, events(), args.verbose)
    say(
        f"done: f_r up to {data['slice']['max']:.4g} /sr on the slice, mean directional "
        f"albedo {data['albedo']['mean_total']:.3f}; slice.exr, slice.png, lobe.svg, "
        f"albedo.csv and plot.json in {out}"
    )


def cmd_scene(args) -> None:
    """A user's scene through its camera: its Cook-Torrance materials against Principled
    conversions (or, with --convert, its Principled materials against Cook-Torrance ones);
    jobs/scene_job.py."""
    from .scene_job import SceneJob, run_scene

    blend = input_file(
        args.blend, ".blend file", missing=f"no such file: {args.blend}; give a .blend file"
    )
    out = check_path(args.out, "--out")
    job = SceneJob(
        blend=blend,
        out=out,
        convert=args.convert,
        light_transport=args.light_transport,
        shader=args.shader,
        g_model=args.g_model,
        diffuse_model=args.diffuse_model,
        energy=args.energy,
        size=args.size,
        samples=args.samples,
        seed=args.seed,
        camera=args.camera,
        principled_distribution=args.principled_distribution,
        verbose=args.verbose,
    )
    what = (
        "Principled materials converted to Cook-Torrance"
        if args.convert
        else "Cook-Torrance materials against Principled conversions"
    )
    say(
        f"scene {blend}: {what}, {args.light_transport} transport, size {args.size}, "
        f"{args.samples} samples -> {out}"
    )
    data = run_scene(job, events())
    for m in data["materials"]:
        de, ratio = m["ciede2000_mean"], m["luminance_ratio"]
        say(
            f"  {m['name']}: {m['pixels']} px, mean CIEDE2000 "
            f"{'-' if de is None else f'{de:.2f}'}, luminance model/Principled "
            f"{'-' if ratio is None else f'{ratio:.4f}'}"
        )
    say(f"done: metrics.json, diff.png, materials.png; open {data['report']}")


def cmd_export(args) -> None:
    """A .blend's Cook-Torrance materials as MaterialX, USD or glTF (jobs/export_job.py)."""
    from .export_job import run_export

    blend = input_file(
        args.blend, ".blend file", missing=f"no such file: {args.blend}; give a .blend file"
    )
    out = check_path(args.out, "--out")
    say(f"export {blend}: its Cook-Torrance materials as {args.format} -> {out}")
    data = run_export(blend, args.format, out, None if args.verbose else os.devnull)
    for note in data["notes"]:
        warn(note)
    for m in data["materials"]:
        what = "exact" if m["exact"] and not m["not_carried"] else "; ".join(m["not_carried"])
        say(f"  {m['name']}: {what or 'exact'}")
    say(f"done: {len(data['written'])} files in {out}")


def build_parser() -> argparse.ArgumentParser:
    parser = Parser(prog="ctlab", description="Cook-Torrance Lab batch tools")
    sub = parser.add_subparsers(dest="command", required=True)
    r = sub.add_parser("render", help="render the sphere matrix with one shader and view")
    r.add_argument(
        "--shader",
        required=True,
        choices=SHADERS,
        help="the OSL shader, the node group (its default IBL: split_sum) or Principled BSDF",
    )
    r.add_argument("--out", required=True, help="output folder")
    r.add_argument(
        "--view", default="full", help="|".join(VIEWS) + "|all (all: one sub-folder per view)"
    )
    r.add_argument(
        "--engine",
        default=ENGINES[0],
        choices=ENGINES,
        help="cycles (CPU; SVM for the node group) or eevee (node group only)",
    )
    r.add_argument(
        "--pixel-centres",
        action="store_true",
        help="every view as one sample at each pixel centre, like the term views "
        "(exact per-pixel values, no anti-aliasing; OSL or node group)",
    )
    add_scene_arguments(r)
    r.set_defaults(func=cmd_render)
    c = sub.add_parser("compare", help="compare two render folders")
    c.add_argument("dir_a")
    c.add_argument("dir_b")
    c.add_argument("--out", required=True, help="output folder for metrics.json and diff.png")
    c.set_defaults(func=cmd_compare)
    b = sub.add_parser(
        "bake",
        help="bake an HDRI's split-sum files (pre-filtered levels, "
        "irradiance, DFG tables), cached by content hash",
    )
    b.add_argument("hdri", help="equirectangular float HDRI (.exr, .hdr)")
    b.add_argument("--out", default=None, help="also copy the files into this folder")
    b.set_defaults(func=cmd_bake)
    m = sub.add_parser("matrix", help="the main job: Cook-Torrance vs Principled, with a report")
    m.add_argument(
        "--out", default=None, help="output folder (default out/matrix; out/parity with --parity)"
    )
    m.add_argument(
        "--parity",
        action="store_true",
        help="the Principled-parity check instead: metallic spheres, Smith G, "
        "Lambert, reference IBL, Sun off, against Principled's single-scatter "
        "GGX, for each of --parity-hdris (or --hdri)",
    )
    m.add_argument(
        "--parity-hdris",
        default=",".join(pipeline.PARITY_HDRIS),
        help="Blender's bundled HDRIs for --parity (default: %(default)s)",
    )
    m.add_argument(
        "--workers",
        type=ascii_int,
        default=1,
        help="render tasks as this many local processes (default 1: in this one)",
    )
    add_scene_arguments(m)
    m.set_defaults(func=cmd_matrix)
    pl = sub.add_parser(
        "plan",
        help="write a batch job's task graph (JOB/plan.json) for "
        "'ctlab task' and 'ctlab merge', or a render farm",
    )
    pl.add_argument(
        "job",
        choices=("matrix", "parity"),
        help="matrix (the main job; --parity for the parity job) or parity",
    )
    pl.add_argument("--out", required=True, help="the job folder")
    pl.add_argument(
        "--openjd",
        action="store_true",
        help="also write an Open Job Description bundle, JOB/openjd/template.json",
    )
    pl.add_argument(
        "--flamenco",
        action="store_true",
        help="also write a Flamenco job type, JOB/flamenco/ctlab-<job>.js",
    )
    pl.add_argument("--parity", action="store_true", help="the Principled-parity job")
    pl.add_argument(
        "--parity-hdris",
        default=",".join(pipeline.PARITY_HDRIS),
        help="Blender's bundled HDRIs for the parity job (default: %(default)s)",
    )
    add_scene_arguments(pl)
    pl.set_defaults(func=cmd_plan)
    t = sub.add_parser("task", help="run one task of a planned job (done already: nothing)")
    t.add_argument("job_dir", help="the job folder (plan.json)")
    t.add_argument("task_id", help="a task id of plan.json")
    t.add_argument("--verbose", action="store_true", help="show Blender's own output")
    t.set_defaults(func=cmd_task)
    mg = sub.add_parser(
        "merge",
        help="compare, plot and write the report of a planned job whose render tasks are done",
    )
    mg.add_argument("job_dir", help="the job folder (plan.json)")
    mg.add_argument("--verbose", action="store_true", help="show Blender's own output")
    mg.set_defaults(func=cmd_merge)
    p = sub.add_parser(
        "plot",
        help="the BRDF plotted from the model's own code: the "
        "theta_h x theta_d slice, lobes and directional albedo",
    )
    p.add_argument("--out", required=True, help="output folder")
    p.add_argument("--metallic", type=ascii_float, default=0.0, help="0 to 1 (default 0)")
    p.add_argument("--smoothness", type=ascii_float, default=0.5, help="0 to 1 (default 0.5)")
    p.add_argument(
        "--albedo",
        default=",".join(map(str, DEFAULT_ALBEDO)),
        help="R,G,B linear albedo, each 0 to 1 (default %(default)s)",
    )
    p.add_argument("--g", dest="g_model", default=G_MODELS[0], help="|".join(G_MODELS))
    p.add_argument(
        "--diffuse", dest="diffuse_model", default=DIFFUSE_MODELS[0], help="|".join(DIFFUSE_MODELS)
    )
    p.add_argument("--units", default=UNITS[0], help="|".join(UNITS))
    p.add_argument("--energy", default=ENERGY_MODES[0], help="|".join(ENERGY_MODES))
    p.add_argument(
        "--shader",
        default="osl",
        choices=IMPLEMENTATIONS,
        help="the implementation that evaluates the model (default osl)",
    )
    p.add_argument(
        "--view",
        action="append",
        default=None,
        help="also slice these term views (comma list, repeatable): "
        "D, F, G, specular_brdf, diffuse_brdf, NdotL, NdotV, NdotH, VdotH",
    )
    p.add_argument(
        "--compare",
        action="append",
        default=None,
        help="overlay a variant: KEY=VALUE with KEY g, diffuse or energy (comma "
        "list, repeatable), e.g. g=smith_ggx_correlated,g=unity_smith_joint",
    )
    p.add_argument("--verbose", action="store_true", help="show Blender's own output")
    p.set_defaults(func=cmd_plot)
    s = sub.add_parser(
        "scene",
        help="a .blend's own scene through its camera: its "
        "Cook-Torrance materials against Principled BSDF "
        "conversions, per material (never saved)",
    )
    s.add_argument("blend", help="the .blend file (opened, never written)")
    s.add_argument("--out", required=True, help="output folder")
    s.add_argument(
        "--convert",
        action="store_true",
        help="the other way: the scene's Principled materials converted to the "
        "model, the originals as the reference",
    )
    s.add_argument(
        "--light-transport",
        dest="light_transport",
        default="scene",
        choices=LIGHT_TRANSPORTS,
        help="for the model materials (default scene: Cycles path traces the model's closures)",
    )
    s.add_argument(
        "--shader",
        default=None,
        choices=IMPLEMENTATIONS,
        help="the model's implementation (default: each material's own; osl with --convert)",
    )
    s.add_argument(
        "--g",
        dest="g_model",
        default=None,
        choices=G_MODELS,
        help="G for every model material (default: each material's own)",
    )
    s.add_argument(
        "--diffuse",
        dest="diffuse_model",
        default=None,
        choices=DIFFUSE_MODELS,
        help="diffuse for every model material (default: each material's own)",
    )
    s.add_argument(
        "--energy",
        default=None,
        choices=ENERGY_MODES,
        help="energy for every model material (default: each material's own)",
    )
    s.add_argument(
        "--principled-distribution",
        dest="principled_distribution",
        default=None,
        choices=("auto", "GGX", "MULTI_GGX"),
        help="the conversions' GGX (default auto: GGX, the model's single "
        "scattering; MULTI_GGX for energy compensated)",
    )
    s.add_argument(
        "--size",
        type=ascii_int,
        default=256,
        help="the longer image side in pixels (the camera's aspect is kept; default %(default)s)",
    )
    s.add_argument(
        "--samples",
        type=ascii_int,
        default=64,
        help="samples per pixel, both renders (default %(default)s)",
    )
    s.add_argument("--seed", type=ascii_int, default=0, help="the renders' seed (default 0)")
    s.add_argument("--camera", default=None, help="a camera object (default: the scene's)")
    s.add_argument("--verbose", action="store_true", help="show Blender's own output")
    s.set_defaults(func=cmd_scene)
    from .export_job import FORMATS

    e = sub.add_parser(
        "export",
        help="a .blend's Cook-Torrance materials as MaterialX (.mtlx per material), USD "
        "(UsdShade materials with the MaterialX network) or glTF (metallic-roughness)",
    )
    e.add_argument("blend", help="the .blend file (opened, never written)")
    e.add_argument("--format", required=True, choices=FORMATS, help="|".join(FORMATS))
    e.add_argument("--out", required=True, help="output folder (the images go to textures/)")
    e.add_argument("--verbose", action="store_true", help="show Blender's own output")
    e.set_defaults(func=cmd_export)
    return parser


def fill_defaults(args, defaults: dict) -> None:
    for key, value in defaults.items():
        if getattr(args, key, None) is None:
            setattr(args, key, value)


VALUE_FLAGS = {a.flag for a in SCENE_ARGS if not a.flag_only} | {
    "--out",
    "--view",
    "--engine",
    "--shader",
    "--parity-hdris",
    "--metallic",
    "--smoothness",
    "--compare",
    "--camera",
    "--seed",
    "--workers",
    "--format",
}


def main(argv_=None) -> int:
    parser = build_parser()
    argv_ = sys.argv[1:] if argv_ is None else list(argv_)
    try:
        try:
            args = parser.parse_args(join_negative_values(argv_, VALUE_FLAGS))
        except SystemExit as exc:  # --help
            return EXIT_BAD_INPUT if exc.code else 0
        if args.command != "plan":
            fill_defaults(args, PARITY_DEFAULTS if getattr(args, "parity", False) else DEFAULTS)
        args.func(args)
    except UserError as exc:
        one_line = " ".join(str(exc).split())  # a library's message may hold newlines
        print(f"ctlab: error: {one_line}", file=sys.stderr, flush=True)
        return EXIT_BAD_INPUT
    except (Cancelled, KeyboardInterrupt):
        print("ctlab: cancelled; finished outputs are kept", file=sys.stderr, flush=True)
        return EXIT_CANCELLED
    return 0
