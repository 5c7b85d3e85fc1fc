"""The command line: ``render``, ``compare``, ``bake`` and ``matrix`` (scripts/ctlab.py is the
entry).

Bad input gets a one-line message naming the problem and exit status 2, and nothing is
written. Blender's own per-tile output goes to a log file in the system temp folder; the command
prints its own progress.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import tempfile
import time
from pathlib import Path

from .errors import UserError
from .params import (DIFFUSE_MODELS, G_MODELS, IBL_MODES, MATRIX_ALBEDO, UNITS, VIEWS,
                     ModelOptions)

EXIT_BAD_INPUT = 2
# Blender's own per-tile output goes here, never into the user's folders (--verbose shows it).
BLENDER_LOG = Path(tempfile.gettempdir()) / f"ctlab-blender-{os.getpid()}.log"


def parse_vector(text: str, n: int, what: str) -> tuple:
    try:
        values = tuple(float(x) for x in text.split(","))
    except ValueError:
        values = ()
    if len(values) != n or not all(math.isfinite(v) for v in values):
        raise UserError(f"malformed {what} {text!r}; give {n} comma-separated numbers")
    return values


def parse_grid(text: str) -> tuple:
    parts = text.lower().split("x")
    if len(parts) != 2 or not all(p.isdigit() for p in parts):
        raise UserError(f"malformed grid {text!r}; give ROWSxCOLS, e.g. 7x7")
    return int(parts[0]), int(parts[1])


def progress(message: str) -> None:
    print(f"[ctlab {time.strftime('%H:%M:%S')}] {message}", flush=True)


def bake_progress(fraction: float, message: str) -> None:
    progress(f"  bake {100 * fraction:3.0f}%: {message}")


EXIT_CANCELLED = 130


class Cancelled(Exception):
    """The user cancelled the job (the file named by $CTLAB_CANCEL_FILE exists)."""


def check_cancelled() -> None:
    """Between steps: stop when the parent asked (background_job.Job.cancel)."""
    flag = os.environ.get("CTLAB_CANCEL_FILE")
    if flag and os.path.exists(flag):
        raise Cancelled()


def warn(message: str) -> None:
    print(f"ctlab: warning: {message}", file=sys.stderr, flush=True)


# ---------------------------------------------------------------------------------------

def add_scene_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--grid", default=None,
                   help="ROWSxCOLS of the sphere matrix (default 7x7; 5x3 with --parity)")
    p.add_argument("--size", type=int, default=None,
                   help="image width and height in pixels (default 512; 384 with --parity)")
    p.add_argument("--samples", type=int, default=None,
                   help="render samples per pixel (default 64; 256 with --parity)")
    p.add_argument("--hdri", default="", help="equirectangular HDRI (default: Blender's forest.exr)")
    p.add_argument("--hdri-strength", type=float, default=1.0)
    p.add_argument("--hdri-rotation", type=float, default=0.0, help="degrees about Z")
    p.add_argument("--sun-dir", default="-0.45,-0.55,0.70", help="X,Y,Z toward the Sun")
    p.add_argument("--sun-strength", type=float, default=1.0, help="Sun irradiance (W/m^2)")
    p.add_argument("--albedo", default=",".join(map(str, MATRIX_ALBEDO)),
                   help="R,G,B linear albedo (default: gold)")
    p.add_argument("--ibl", default=None,
                   help="indirect light: " + "|".join(IBL_MODES) + " (default: reference; "
                        "split_sum for the node group; split_sum and unity use the files of "
                        "'ctlab bake', made and cached on demand)")
    p.add_argument("--g", dest="g_model", default=G_MODELS[0], help="|".join(G_MODELS))
    p.add_argument("--diffuse", dest="diffuse_model", default=DIFFUSE_MODELS[0],
                   help="|".join(DIFFUSE_MODELS))
    p.add_argument("--units", default=UNITS[0], help="|".join(UNITS))
    p.add_argument("--env-samples", type=int, default=4,
                   help="environment samples per shading point and render sample (each of "
                        "BRDF and environment sampling)")
    p.add_argument("--env-visibility", action="store_true",
                   help="trace environment samples for occlusion by other objects")
    p.add_argument("--principled-distribution", default="MULTI_GGX", choices=("MULTI_GGX", "GGX"))
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--verbose", action="store_true", help="show Blender's own output")


DEFAULTS = {"grid": "7x7", "size": 512, "samples": 64}
PARITY_DEFAULTS = {"grid": "5x3", "size": 384, "samples": 256}


def fill_defaults(args, defaults: dict) -> None:
    for key, value in defaults.items():
        if getattr(args, key, None) is None:
            setattr(args, key, value)


def matrix_settings(args, shader: str, view: str, ibl: str | None = None):
    """The scene and model settings from the command line; ``ibl`` overrides --ibl."""
    from .scene_builder import MatrixSettings
    if view not in VIEWS and view != "all":
        raise UserError(f"unknown view {view!r}; choose one of: {', '.join(VIEWS)}")
    rows, cols = parse_grid(args.grid)
    if args.samples < 1 or args.samples > 65536:
        raise UserError(f"samples {args.samples} out of range; use 1 to 65536")
    ibl = ibl or args.ibl or ("split_sum" if shader == "nodes" else IBL_MODES[0])
    model = ModelOptions(view=view, g_model=args.g_model, diffuse_model=args.diffuse_model,
                         units=args.units, ibl=ibl, env_samples=args.env_samples,
                         env_visibility=args.env_visibility, seed=args.seed)
    s = MatrixSettings(rows=rows, cols=cols, hdri=args.hdri, hdri_strength=args.hdri_strength,
                       hdri_rotation=args.hdri_rotation,
                       sun_to_light=parse_vector(args.sun_dir, 3, "sun direction"),
                       sun_strength=args.sun_strength,
                       albedo=parse_vector(args.albedo, 3, "albedo"), shader=shader,
                       principled_distribution=args.principled_distribution,
                       width=args.size, height=args.size, model=model)
    s.validate()
    if s.hdri:
        from .hdri import load_hdri
        load_hdri(s.hdri_path())
    return s


def render_views(settings, out_dirs: dict, samples: int, verbose: bool, report=None,
                 pixel_centres: bool = False, engine: str = "cycles") -> dict:
    """Build the matrix once in a fresh empty scene and render each view into its folder
    (``{view: folder}``); the shader compiles once. Returns the last scene description.
    ``pixel_centres``: every view as one sample at each pixel centre (no anti-aliasing)."""
    import bpy
    from . import materials, renderer, scene_builder
    for out_dir in out_dirs.values():
        renderer.check_writable(out_dir)
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    description = scene_builder.build_matrix(scene, settings, bake_progress)
    mat = next((m for m in bpy.data.materials if m.get(scene_builder.TAG)), None)
    log = None if verbose else BLENDER_LOG
    for i, (view, out_dir) in enumerate(out_dirs.items()):
        settings.model.view = view
        description["model"] = settings.model.as_dict()
        if settings.shader == "osl":
            materials.set_options(mat, settings.model)
        elif settings.shader == "nodes":
            materials.set_group_options(materials.group_node(mat), settings.model)
        renderer.configure(scene, settings.shader, view, samples, settings.model.seed,
                           pixel_centres, engine)
        description = renderer.render(scene, out_dir, description, log)
        if report:
            report(i, view, description)
    return description


def render_one(settings, out_dir: Path, samples: int, verbose: bool, engine="cycles") -> dict:
    """Build the matrix in a fresh empty scene and render its view into out_dir."""
    return render_views(settings, {settings.model.view: Path(out_dir)}, samples, verbose,
                        engine=engine)


def cmd_render(args) -> None:
    views = VIEWS if args.view == "all" else (args.view,)
    if args.engine == "eevee" and args.shader != "nodes":
        raise UserError("--engine eevee renders the node group only; add --shader nodes")
    settings = matrix_settings(args, args.shader, views[0])
    out = Path(args.out)
    dirs = {v: out / v for v in views} if args.view == "all" else {views[0]: out}
    progress(f"rendering {settings.shader} view={args.view} grid={args.grid} size={args.size} "
             f"samples={args.samples} -> {out}")

    def report(i, view, d):
        progress(f"[{i + 1}/{len(dirs)}] {view}: {d['render_seconds']:.1f} s -> {dirs[view]}")
    render_views(settings, dirs, args.samples, args.verbose, report, args.pixel_centres,
                 args.engine)
    progress("done: render.exr, render.png and scene.json in each folder")


def cmd_compare(args) -> None:
    from .compare import compare
    result = compare(Path(args.dir_a), Path(args.dir_b), Path(args.out))
    o = result["overall"]
    progress(f"compared {len(result['cells'])} cells: mean CIEDE2000 {o['ciede2000_mean']:.2f}, "
             f"PSNR {o['psnr_db']:.2f} dB -> {Path(args.out) / 'metrics.json'}, diff.png")


def cmd_bake(args) -> None:
    """Bake the split-sum files of an HDRI (cached by content hash), optionally copied to --out."""
    from . import ibl_bake
    from .renderer import check_writable
    if args.out:
        check_writable(Path(args.out))
    progress(f"baking {args.hdri}")
    folder = ibl_bake.bake(Path(args.hdri), bake_progress, warn)
    if args.out:
        ibl_bake.export(folder, Path(args.out))
        folder = Path(args.out)
    names = ", ".join(sorted(p.name for p in folder.iterdir() if not p.name.startswith(".")))
    progress(f"done: {folder}: {names}")


SMITH = {"g_model": "smith_ggx_correlated"}
# The matrix job's renders: (folder, label, shader, IBL mode, settings changed from the
# command line's). The last three are the intermediate configurations of the attribution.
MATRIX_RENDERS = (
    ("cook_torrance", "Cook-Torrance (OSL, reference IBL)", "osl", "reference", {}),
    ("principled", "Principled BSDF", "principled", "reference", {}),
    ("split_sum", "Cook-Torrance (OSL, split-sum IBL)", "osl", "split_sum", {}),
    ("unity", "Cook-Torrance (OSL, Unity IBL)", "osl", "unity", {}),
    ("nodes", "Cook-Torrance (node group, split-sum IBL)", "nodes", "split_sum", {}),
    ("attr_smith", "Cook-Torrance with Smith G", "osl", "reference", SMITH),
    ("attr_smith_lambert", "Cook-Torrance with Smith G and Lambert diffuse", "osl", "reference",
     dict(SMITH, diffuse_model="lambert")),
    ("attr_principled_ggx", "Principled BSDF (single-scatter GGX)", "principled", "reference",
     {"principled_distribution": "GGX"}))
# Its comparisons: (folder, render, against). The model against Principled; the baked IBL
# modes against the reference integration (the accuracy study of the split-sum); the node
# group against the OSL shader in the same mode (parity); the attribution's steps.
MATRIX_COMPARISONS = (("compare", "cook_torrance", "principled"),
                      ("compare_split_sum", "split_sum", "cook_torrance"),
                      ("compare_unity", "unity", "cook_torrance"),
                      ("compare_nodes", "nodes", "split_sum"),
                      ("compare_attr_smith", "attr_smith", "principled"),
                      ("compare_attr_smith_lambert", "attr_smith_lambert", "principled"),
                      ("compare_attr_ggx", "attr_smith_lambert", "attr_principled_ggx"))
# The attribution: the error against Principled after each switch (comparison folder, the
# switch it follows).
ATTRIBUTION = (("compare", "seed model"),
               ("compare_attr_smith", "G: Cook-Torrance to Smith"),
               ("compare_attr_smith_lambert", "diffuse: Disney to Lambert"),
               ("compare_attr_ggx", "Principled: multiscatter to single-scatter GGX"))
# The white furnace (addon/energy.py): (folder, G model).
FURNACE_RENDERS = (("furnace_cook_torrance", "cook_torrance"),
                   ("furnace_smith", "smith_ggx_correlated"))


def with_overrides(settings, overrides: dict):
    """A copy of the settings with model switches or scene fields replaced."""
    import copy
    s = copy.deepcopy(settings)
    for key, value in overrides.items():
        setattr(s.model if hasattr(s.model, key) else s, key, value)
    s.validate()
    return s


def cmd_matrix(args) -> None:
    """The main job: the OSL shader against Principled BSDF, and the baked IBL modes against
    the reference integration, compared cell by cell, with a report."""
    from .compare import compare
    from .renderer import check_writable
    from .report import write_report
    from . import energy
    if args.parity:
        return cmd_parity(args)
    out = Path(args.out or "out/matrix")
    settings = {}
    for folder, _, shader, ibl, overrides in MATRIX_RENDERS:
        settings[folder] = with_overrides(matrix_settings(args, shader, "full", ibl), overrides)
    for folder, g_model in FURNACE_RENDERS:
        settings[folder] = energy.furnace_settings(g_model, args.env_samples, args.seed)
    check_writable(out)
    steps = len(settings) + 2
    timings, scenes = {}, {}
    labels = {folder: label for folder, label, *_ in MATRIX_RENDERS}
    labels.update({folder: f"White furnace, {g} G" for folder, g in FURNACE_RENDERS})
    for i, (folder, s) in enumerate(settings.items()):
        check_cancelled()
        progress(f"[{i + 1}/{steps}] {labels[folder]}: grid {s.rows}x{s.cols}, "
                 f"{s.width}x{s.height} px, {args.samples} samples")
        scenes[folder] = render_one(s, out / folder, args.samples, args.verbose)
        timings[labels[folder]] = scenes[folder]["render_seconds"]
        progress(f"      {timings[labels[folder]]:.1f} s")
    check_cancelled()
    progress(f"[{steps - 1}/{steps}] comparing")
    results = {cmp_dir: compare(out / a, out / b, out / cmp_dir)
               for cmp_dir, a, b in MATRIX_COMPARISONS}
    from .compare import read_image
    furnace = {g: energy.directional_albedo(read_image(out / folder / "render.exr"),
                                            scenes[folder])
               for folder, g in FURNACE_RENDERS}
    progress(f"[{steps}/{steps}] writing the report")
    report = write_report(out, [(a, b, cmp_dir, labels[a], labels[b], results[cmp_dir])
                                for cmp_dir, a, b in MATRIX_COMPARISONS[:4]],
                          scenes["cook_torrance"], timings,
                          attribution=[(label, results[c]) for c, label in ATTRIBUTION],
                          furnace=furnace)
    de = {cmp_dir: results[cmp_dir]["overall"]["ciede2000_mean"] for cmp_dir in results}
    progress(f"done: mean CIEDE2000 against Principled {de['compare']:.2f} "
             f"(PSNR {results['compare']['overall']['psnr_db']:.2f} dB); split-sum against "
             f"the reference {de['compare_split_sum']:.2f}, Unity {de['compare_unity']:.2f}; "
             f"node group against OSL {de['compare_nodes']:.3f}; open {report}")


PARITY_HDRIS = ("forest", "studio")
PARITY_BOUND = 1.0            # per-sphere mean CIEDE2000 (issue 6)
PARITY_MODEL = dict(g_model="smith_ggx_correlated", diffuse_model="lambert", metallic=1.0,
                    sun_strength=0.0, mutual_shadows=False)


def cmd_parity(args) -> None:
    """The Principled-parity check: with Smith G, Lambert diffuse, metallic 1, the Sun off and
    no sphere shadowing another, the model is Principled BSDF's single-scatter GGX metal, so
    our reference integration and Cycles' path tracer must agree up to noise."""
    from .compare import compare
    from .paths import bundled_hdri
    from .renderer import check_writable
    from .report import write_parity_report
    out = Path(args.out or "out/parity")
    if args.hdri:
        hdris = [Path(args.hdri)]
    else:
        names = [n.strip() for n in args.parity_hdris.split(",") if n.strip()]
        hdris = [bundled_hdri(n) for n in names]
        missing = [str(h) for h in hdris if not h.is_file()]
        if missing or not hdris:
            raise UserError(f"unknown bundled HDRI in --parity-hdris {args.parity_hdris!r}; "
                            "choose from: city, courtyard, forest, interior, night, studio, "
                            "sunrise, sunset")
    jobs = []
    for hdri in hdris:
        args.hdri = str(hdri)
        ct = with_overrides(matrix_settings(args, "osl", "full", "reference"), PARITY_MODEL)
        pr = with_overrides(matrix_settings(args, "principled", "full", "reference"),
                            dict(PARITY_MODEL, principled_distribution="GGX"))
        jobs.append((hdri.stem, ct, pr))
    check_writable(out)
    steps, step, entries = 2 * len(jobs) + 1, 0, []
    for name, ct, pr in jobs:
        scenes = {}
        for folder, s in (("cook_torrance", ct), ("principled", pr)):
            check_cancelled()
            step += 1
            progress(f"[{step}/{steps}] {name}: {folder}, grid {args.grid}, {args.size} px, "
                     f"{args.samples} samples")
            scenes[folder] = render_one(s, out / name / folder, args.samples, args.verbose)
        result = compare(out / name / "cook_torrance", out / name / "principled",
                         out / name / "compare")
        worst = max(c["ciede2000_mean"] for c in result["cells"])
        progress(f"      {name}: mean CIEDE2000 {result['overall']['ciede2000_mean']:.2f}, "
                 f"worst sphere {worst:.2f} (bound {PARITY_BOUND})")
        entries.append((name, result, scenes["cook_torrance"]))
    progress(f"[{steps}/{steps}] writing the report")
    report = write_parity_report(out, entries, PARITY_BOUND)
    verdict = all(max(c["ciede2000_mean"] for c in r["cells"]) <= PARITY_BOUND
                  for _, r, _ in entries)
    progress(f"done: parity {'holds' if verdict else 'FAILS'} (every sphere's mean CIEDE2000 "
             f"<= {PARITY_BOUND}); open {report}")


def build_parser() -> argparse.ArgumentParser:
    from .renderer import ENGINES
    from .scene_builder import SHADERS
    parser = argparse.ArgumentParser(prog="ctlab", description="Cook-Torrance Lab batch tools")
    sub = parser.add_subparsers(dest="command", required=True)
    r = sub.add_parser("render", help="render the sphere matrix with one shader and view")
    r.add_argument("--shader", required=True, choices=SHADERS,
                   help="the OSL shader, the node group (its default IBL: split_sum) or "
                        "Principled BSDF")
    r.add_argument("--out", required=True, help="output folder")
    r.add_argument("--view", default="full",
                   help="|".join(VIEWS) + "|all (all: one sub-folder per view)")
    r.add_argument("--engine", default=ENGINES[0], choices=ENGINES,
                   help="cycles (CPU; SVM for the node group) or eevee (node group only)")
    r.add_argument("--pixel-centres", action="store_true",
                   help="every view as one sample at each pixel centre, like the term views "
                        "(exact per-pixel values, no anti-aliasing; OSL or node group)")
    add_scene_arguments(r)
    r.set_defaults(func=cmd_render)
    c = sub.add_parser("compare", help="compare two render folders")
    c.add_argument("dir_a")
    c.add_argument("dir_b")
    c.add_argument("--out", required=True, help="output folder for metrics.json and diff.png")
    c.set_defaults(func=cmd_compare)
    b = sub.add_parser("bake", help="bake an HDRI's split-sum files (pre-filtered levels, "
                                    "irradiance, DFG tables), cached by content hash")
    b.add_argument("hdri", help="equirectangular float HDRI (.exr, .hdr)")
    b.add_argument("--out", default="", help="also copy the files into this folder")
    b.set_defaults(func=cmd_bake)
    m = sub.add_parser("matrix", help="the main job: Cook-Torrance vs Principled, with a report")
    m.add_argument("--out", default=None,
                   help="output folder (default out/matrix; out/parity with --parity)")
    m.add_argument("--parity", action="store_true",
                   help="the Principled-parity check instead: metallic spheres, Smith G, "
                        "Lambert, reference IBL, Sun off, against Principled's single-scatter "
                        "GGX, for each of --parity-hdris (or --hdri)")
    m.add_argument("--parity-hdris", default=",".join(PARITY_HDRIS),
                   help="Blender's bundled HDRIs for --parity (default: %(default)s)")
    add_scene_arguments(m)
    m.set_defaults(func=cmd_matrix)
    return parser


def main(argv=None) -> int:
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:                   # argparse already printed one line
        return EXIT_BAD_INPUT if exc.code else 0
    fill_defaults(args, PARITY_DEFAULTS if getattr(args, "parity", False) else DEFAULTS)
    try:
        args.func(args)
    except UserError as exc:
        print(f"ctlab: error: {exc}", file=sys.stderr, flush=True)
        return EXIT_BAD_INPUT
    except Cancelled:
        print("ctlab: cancelled; finished outputs are kept", file=sys.stderr, flush=True)
        return EXIT_CANCELLED
    return 0
