"""``ctlab import-unity``: a Unity project's Standard materials as Cook-Torrance materials in
a new .blend (jobs/unity_import_job.py)."""

from __future__ import annotations

import os

from .options import FORCE, OUT, VERBOSE, Command, Option
from .output import say, warn
from ...core.paths import clean

UNITY_PATH = Option(
    "path", "a Unity .mat file, or a Unity project or Assets folder (read, never written)"
)


def run(args) -> None:
    """A Unity project's Standard materials as Cook-Torrance materials (a new .blend)."""
    from ..unity_import_job import run_import

    path = clean(args.path, "Unity path")
    out = clean(args.out, "--out")
    say(f"import-unity {path}: its Standard materials as Cook-Torrance -> {out}")
    log = None if args.verbose else os.devnull
    data = run_import(path, out, log, force=args.force)
    for line in data["skipped"]:
        say(f"  skipped {line}")
    for line in data["warnings"]:
        warn(line)
    for m in data["materials"]:
        what = "; ".join(m["not_carried"])
        say(f"  {m['name']}: imported" + (f" (not carried: {what})" if what else ""))
    say(
        f"done: {len(data['materials'])} material(s) in {out} (Unity's colours are read as a "
        "Linear colour-space project shows them)"
    )


COMMAND = Command(
    "import-unity",
    "a Unity project's built-in Standard materials (.mat) as Cook-Torrance materials in a new "
    ".blend",
    (
        UNITY_PATH,
        OUT.but(help="the .blend to write (a new file)"),
        FORCE.but(help="replace an existing --out .blend (any other file is refused)"),
        VERBOSE,
    ),
    run,
)
