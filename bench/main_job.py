"""The main job: ``ctlab matrix`` at its defaults, the whole process, and what ``--textured``
(the seed's textures on every sphere) adds to it (scripts/bench.py --only main)."""

import resource
import statistics
import subprocess
import sys
import time
from pathlib import Path

from bench.common import CTLAB


def _cpu_of_children() -> float:
    """User + system CPU seconds of every child process waited for so far."""
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def _matrix(work: Path, name: str, *extra: str) -> tuple:
    """One `ctlab matrix` process in an empty output folder: its wall time and its CPU time
    (user + system, its threads together) in seconds. Where other work shares the machine,
    the wall time grows with the waits; the CPU time counts only the process's own work."""
    out = work / name
    cpu = _cpu_of_children()
    start = time.perf_counter()
    done = subprocess.run(
        [sys.executable, str(CTLAB), "matrix", *extra, "--out", str(out)],
        capture_output=True,
        text=True,
    )
    wall = time.perf_counter() - start
    cpu = _cpu_of_children() - cpu
    if done.returncode != 0:
        raise SystemExit(f"bench: ctlab matrix {' '.join(extra)} failed:\n{done.stderr[-2000:]}")
    print(f"main job {' '.join(extra) or '(plain)'}: {wall:.1f} s (CPU {cpu:.1f} s)", flush=True)
    return wall, cpu


def bench_main(quick: bool, work: Path, pairs: int = 2) -> dict:
    """`ctlab matrix` at its defaults, the whole process, in an empty output folder (the
    split-sum bake cached, as after any earlier run). Then ``pairs`` pairs of the plain job and
    `--textured`, alternating (T P, P T, ...) so that a drift of the machine's load falls on
    both; each pair's ratio textured / plain, and their median. The first run fills the caches
    (the bake, the BRDF plots), which the textures do not key, so every paired run finds them
    warm. Each ratio by wall time, and by CPU time beside it. ``quick``: one pair."""
    wall, _ = _matrix(work, "matrix")
    runs = {"plain": [], "textured": []}
    for i in range(1 if quick else max(1, pairs)):
        order = ("textured", "plain") if i % 2 == 0 else ("plain", "textured")
        for kind in order:
            extra = ("--textured",) if kind == "textured" else ()
            runs[kind].append(_matrix(work, f"{kind}-{i}", *extra))

    def median_ratio(k):
        return round(
            statistics.median(t[k] / p[k] for t, p in zip(runs["textured"], runs["plain"])), 3
        )

    return {
        "wall_seconds": round(wall, 1),
        "command": "scripts/ctlab.py matrix",
        "plain_seconds": [round(r[0], 1) for r in runs["plain"]],
        "textured_seconds": [round(r[0], 1) for r in runs["textured"]],
        "plain_cpu_seconds": [round(r[1], 1) for r in runs["plain"]],
        "textured_cpu_seconds": [round(r[1], 1) for r in runs["textured"]],
        "textured_ratio": median_ratio(0),
        "textured_cpu_ratio": median_ratio(1),
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
    if "textured_cpu_ratio" in section:
        plain = ", ".join(f"{t:.1f}" for t in section["plain_cpu_seconds"])
        textured = ", ".join(f"{t:.1f}" for t in section["textured_cpu_seconds"])
        lines += [
            "",
            f"The same runs by CPU time (user + system, both cores together): plain {plain} s, "
            f"textured {textured} s; textured / plain, median over the pairs: "
            f"**{section['textured_cpu_ratio']:.3f}**.",
        ]
    return lines
