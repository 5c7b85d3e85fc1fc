"""The main job: ``ctlab matrix`` at its defaults, the whole process (scripts/bench.py
--only main)."""

import subprocess
import sys
import time
from pathlib import Path

from bench.common import CTLAB


def bench_main(quick: bool, work: Path) -> dict:
    """`ctlab matrix` at its defaults, the whole process, in an empty output folder (the
    split-sum bake cached, as after any earlier run); ``quick`` changes nothing."""
    out = work / "matrix"
    start = time.perf_counter()
    done = subprocess.run(
        [sys.executable, str(CTLAB), "matrix", "--out", str(out)], capture_output=True, text=True
    )
    wall = time.perf_counter() - start
    if done.returncode != 0:
        raise SystemExit(f"bench: ctlab matrix failed:\n{done.stderr[-2000:]}")
    print(f"main job: {wall:.1f} s", flush=True)
    return {"wall_seconds": round(wall, 1), "command": "scripts/ctlab.py matrix"}


def main_table(section: dict) -> list:
    return [
        f"`{section['command']}` at its defaults: "
        f"**{section['wall_seconds']:.0f} s** wall (the whole process).",
    ]
