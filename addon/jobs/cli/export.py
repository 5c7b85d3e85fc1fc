"""``ctlab export``: a .blend's Cook-Torrance materials as MaterialX, USD or glTF
(jobs/export_job.py)."""

from __future__ import annotations

import os

from .options import BLEND, FORCE, FORMAT, OUT, VERBOSE, Command, check_path
from .output import say, warn
from ...core.export.network import EXACT
from ...core.paths import input_file


def run(args) -> None:
    """A .blend's Cook-Torrance materials as MaterialX, USD or glTF (jobs/export_job.py)."""
    from ..export_job import run_export

    blend = input_file(
        args.blend, ".blend file", missing=f"no such file: {args.blend}; give a .blend file"
    )
    out = check_path(args.out, "--out")
    say(f"export {blend}: its Cook-Torrance materials as {args.format} -> {out}")
    log = None if args.verbose else os.devnull
    data = run_export(blend, args.format, out, log, force=args.force)
    for note in data["notes"]:
        warn(note)
    for m in data["materials"]:
        # MaterialX's reference GLSL adds GGX energy compensation: exact only where the
        # closures are single scattering, as Cycles' OSL (core.export.network.EXACT)
        what = EXACT if m["exact"] and not m["not_carried"] else "; ".join(m["not_carried"])
        say(f"  {m['name']}: {what or EXACT}")
    if args.format == "unity":
        from ...core.unity.mat import COLOUR_SPACE_NOTE

        say(COLOUR_SPACE_NOTE)
    say(f"done: {len(data['written'])} files in {out}")


COMMAND = Command(
    "export",
    "a .blend's Cook-Torrance materials as MaterialX (.mtlx per material), USD (UsdShade "
    "materials with the MaterialX network), glTF (metallic-roughness) or Unity (Standard "
    ".mat files with .meta)",
    (BLEND, FORMAT, OUT.but(help="output folder (the images go to textures/)"), FORCE, VERBOSE),
    run,
)
