"""``ctlab render``: the sphere matrix with one shader and view (or every view), through
jobs/pipeline.py ``render_views``."""

from __future__ import annotations

from .options import (
    ENGINE,
    MATRIX_OPTIONS,
    OUT,
    PIXEL_CENTRES,
    SHADER,
    VIEW,
    Command,
    check_path,
)
from .output import events, progress, say
from .sphere_matrix import settings_from
from .. import pipeline
from ...core.errors import UserError
from ...core.model import SHADERS, VIEWS


def run(args) -> None:
    views = VIEWS if args.view == "all" else (args.view,)
    if args.engine == "eevee" and args.shader != "nodes":
        raise UserError("--engine eevee renders the node group only; add --shader nodes")
    settings = settings_from(args, args.shader, views[0])
    if args.pixel_centres and args.light_transport == "scene":
        raise UserError(
            "--pixel-centres renders one sample at each pixel centre; the scene "
            "transport is path traced: use --light-transport lab"
        )
    from ...blender.paths import resolve_hdri
    from ...core.hdri import load_hdri

    load_hdri(resolve_hdri(settings.hdri))
    out = check_path(args.out, "--out")
    dirs = {v: out / v for v in views} if args.view == "all" else {views[0]: out}
    say(
        f"rendering {settings.shader} view={args.view} grid={args.grid} size={args.size} "
        f"samples={args.samples} -> {out}"
    )

    def report(i, view, d):
        progress(i + 1, len(dirs), f"{view}: {d['render_seconds']:.1f} s -> {dirs[view]}")

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


COMMAND = Command(
    "render",
    "render the sphere matrix with one shader and view",
    (
        # a shader: an implementation or the reference, Principled
        SHADER.but(
            default=None,
            required=True,
            choices=SHADERS,
            help="the OSL shader, the node group (its default IBL: split_sum) or Principled BSDF",
        ),
        OUT,
        VIEW,
        ENGINE,
        PIXEL_CENTRES,
        *MATRIX_OPTIONS,
    ),
    run,
)
