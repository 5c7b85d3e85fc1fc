"""The main job: ``ctlab matrix`` at its defaults, the whole process, and what ``--textured``
(the seed's textures on every sphere) adds to it (scripts/bench.py --only main)."""

import statistics
import subprocess
import sys
import time
from pathlib import Path

from bench.common import CTLAB


def _matrix(work: Path, name: str, *extra: str) -> float:
    """One `ctlab matrix` process in an empty output folder: its wall time in seconds."""
    out = work / name
    start = time.perf_counter()
    done = subprocess.run(
        [sys.executable, str(CTLAB), "matrix", *extra, "--out", str(out)],
        capture_output=True,
        text=True,
    )
    wall = time.perf_counter() - start
    if done.returncode != 0:
        raise SystemExit(f"bench: ctlab matrix {' '.join(extra)} failed:\n{done.stderr[-2000:]}")
    print(f"main job {' '.join(extra) or '(plain)'}: {wall:.1f} s", flush=True)
    return wall


def bench_main(quick: bool, work: Path, pairs: int = 2) -> dict:
    """`ctlab matrix` at its defaults, the whole process, in an empty output folder (the
    split-sum bake cached, as after any earlier run). Then ``pairs`` pairs of the plain job and
    `--textured`, alternating (T P, P T, ...) so that a drift of the machine's load falls on
    both; each pair's ratio textured / plain, and their median. The first run fills the caches
    (the bake, the BRDF plots), which the textures do not key, so every paired run finds them
    warm. ``quick``: one pair."""
    wall = _matrix(work, "matrix")
    plain, textured, ratios = [], [], []
    for i in range(1 if quick else max(1, pairs)):
        order = ("textured", "plain") if i % 2 == 0 else ("plain", "textured")
        times = {}
        for kind in order:
            extra = ("--textured",) if kind == "textured" else ()
            times[kind] = _matrix(work, f"{kind}-{i}", *extra)
        plain.append(round(times["plain"], 1))
        textured.append(round(times["textured"], 1))
        ratios.append(times["textured"] / times["plain"])
    return {
        "wall_seconds": round(wall, 1),
        "command": "scripts/ctlab.py matrix",
        "plain_seconds": plain,
        "textured_seconds": textured,
        "textured_ratio": round(statistics.median(ratios), 3),
    }


def main_table(section: dict) -> list:
    lines = [
        f"`{section['command']}` at its defaults: "
        f"**{section['wall_seconds']:.0f} s** wall (the whole process).",
    ]
    if "textured_ratio" in section:
        plain = ", ".join(f"{t:.1f}" for t in section["plain_seconds"])
        textured = ", ".join(f"{t:.1f}" for t in section["textured_seconds"])
        lines += [
            "",
            "With the seed's textures on every sphere (`--textured`), in alternating pairs "
            f"(T P, P T, ...; caches warm): plain {plain} s, textured {textured} s; "
            f"textured / plain, median over the pairs: **{section['textured_ratio']:.3f}**.",
        ]
    return lines
