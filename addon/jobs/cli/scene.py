"""``ctlab scene``: a user's .blend through its camera, its Cook-Torrance materials against
Principled conversions (or, with --convert, its Principled materials against Cook-Torrance
ones), per material; jobs/scene_job.py."""

from __future__ import annotations

from .options import (
    BLEND,
    CAMERA,
    CONVERT,
    DIFFUSE,
    ENERGY,
    G,
    LIGHT_TRANSPORT,
    OUT,
    PRINCIPLED_DISTRIBUTION,
    SAMPLES,
    SEED,
    SHADER,
    SIZE,
    VERBOSE,
    Command,
    check_path,
    per_material,
)
from .output import events, say
from ...core import model
from ...core.paths import input_file


def run(args) -> None:
    """A user's scene through its camera: its Cook-Torrance materials against Principled
    conversions (or, with --convert, its Principled materials against Cook-Torrance ones);
    jobs/scene_job.py."""
    from ..scene_job import SceneJob, run_scene

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


COMMAND = Command(
    "scene",
    "a .blend's own scene through its camera: its Cook-Torrance materials against Principled "
    "BSDF conversions, per material (never saved)",
    (
        BLEND,
        OUT,
        CONVERT,
        # the scene transport by default: a user's objects, where every object and light
        # counts (cli/options.py LIGHT_TRANSPORT says why the matrix's is lab)
        LIGHT_TRANSPORT.but(
            default=model.DEFAULT_TRANSPORT[model.ARTIST],
            choices=LIGHT_TRANSPORT.values,
            help="for the model materials (default scene: Cycles path traces the model's closures)",
        ),
        SHADER.but(
            default=None,
            help="the model's implementation (default: each material's own; osl with --convert)",
        ),
        per_material(G, "G"),
        per_material(DIFFUSE, "diffuse"),
        per_material(ENERGY, "energy"),
        PRINCIPLED_DISTRIBUTION.but(
            default=None,
            choices=("auto", "GGX", "MULTI_GGX"),
            help="the conversions' GGX (default auto: GGX, the model's single scattering; "
            "MULTI_GGX for energy compensated)",
        ),
        SIZE.but(
            default=256,
            help="the longer image side in pixels (the camera's aspect is kept; default "
            "%(default)s)",
        ),
        SAMPLES.but(default=64, help="samples per pixel, both renders (default %(default)s)"),
        SEED.but(help="the renders' seed (default 0)"),
        CAMERA,
        VERBOSE,
    ),
    run,
)
