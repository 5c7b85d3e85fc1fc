"""``ctlab bake``: an HDRI's split-sum files (jobs/pipeline.py ``run_bake``)."""

from __future__ import annotations

from .options import FORCE, HDRI_FILE, OUT, Command, check_path
from .output import events, say, warn
from .. import pipeline


def run(args) -> None:
    """Bake the split-sum files of an HDRI (cached by content hash), optionally copied to --out."""
    hdri = check_path(args.hdri, "HDRI")
    out = None if args.out is None else check_path(args.out, "--out")
    say(f"baking {hdri}")
    folder = pipeline.run_bake(hdri, out, events(), warn, force=args.force)
    names = ", ".join(sorted(p.name for p in folder.iterdir() if not p.name.startswith(".")))
    say(f"done: {folder}: {names}")


COMMAND = Command(
    "bake",
    "bake an HDRI's split-sum files (pre-filtered levels, irradiance, DFG tables), cached by "
    "content hash",
    (
        HDRI_FILE,
        OUT.but(required=False, help="also copy the files into this folder"),
        FORCE,
    ),
    run,
)
