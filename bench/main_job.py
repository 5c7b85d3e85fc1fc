"""The main job: ``ctlab matrix`` at its defaults, the whole process, and what ``--textured``
(the seed's textures on every sphere) adds to it (scripts/bench.py --only main)."""

import statistics
import sys
from pathlib import Path

from bench.common import CTLAB, timed_run

MEASURES = ("wall", "cpu")  # a run's times: wall time, CPU time (bench.common.timed_run)


def _matrix(work: Path, name: str, *extra: str) -> dict:
    """One `ctlab matrix` process in an empty output folder: its wall time and CPU time in
    seconds, {"wall": ..., "cpu": ...}."""
    done, wall, cpu = timed_run(
        [sys.executable, str(CTLAB), "matrix", *extra, "--out", str(work / name)]
    )
    if done.returncode != 0:
        raise SystemExit(f"bench: ctlab matrix {' '.join(extra)} failed:\n{done.stderr[-2000:]}")
    print(f"main job {' '.join(extra) or '(plain)'}: {wall:.1f} s (CPU {cpu:.1f} s)", flush=True)
    return {"wall": wall, "cpu": cpu}


def bench_main(quick: bool, work: Path, pairs: int = 2) -> dict:
    """`ctlab matrix` at its defaults, the whole process, in an empty output folder (the
    split-sum bake cached, as after any earlier run). Then ``pairs`` pairs of the plain job and
    `--textured`, alternating (T P, P T, ...) so that a drift of the machine's load falls on
    both; each pair's ratio textured / plain, and their median. The first run fills the caches
    (the bake, the BRDF plots), which the textures do not key, so every paired run finds them
    warm. Each ratio by wall time, and by CPU time beside it. ``quick``: one pair."""
    first = _matrix(work, "matrix")
    runs = {"plain": [], "textured": []}
    for i in range(1 if quick else max(1, pairs)):
        order = ("textured", "plain") if i % 2 == 0 else ("plain", "textured")
        for kind in order:
            extra = ("--textured",) if kind == "textured" else ()
            runs[kind].append(_matrix(work, f"{kind}-{i}", *extra))

    section = {"wall_seconds": round(first["wall"], 1), "command": "scripts/ctlab.py matrix"}
    for m in MEASURES:
        tag = "" if m == "wall" else f"_{m}"  # the wall time's keys as they were before
        for kind, times in runs.items():
            section[f"{kind}{tag}_seconds"] = [round(t[m], 1) for t in times]
        ratios = (t[m] / p[m] for t, p in zip(runs["textured"], runs["plain"]))
        section[f"textured{tag}_ratio"] = round(statistics.median(ratios), 3)
    return section


def _pairs(section: dict, tag: str) -> str:
    """The pairs' times and their median ratio, for the keys of one measure (``tag``)."""
    plain, textured = (
        ", ".join(f"{t:.1f}" for t in section[f"{kind}{tag}_seconds"])
        for kind in ("plain", "textured")
    )
    return (
        f"plain {plain} s, textured {textured} s; textured / plain, median over the pairs: "
        f"**{section[f'textured{tag}_ratio']:.3f}**."
    )


def main_table(section: dict) -> list:
    lines = [
        f"`{section['command']}` at its defaults: "
        f"**{section['wall_seconds']:.0f} s** wall (the whole process).",
    ]
    if "textured_ratio" in section:
        lines += [
            "",
            "With the seed's textures on every sphere (`--textured`), in alternating pairs "
            f"(T P, P T, ...; caches warm): {_pairs(section, '')}",
        ]
    if "textured_cpu_ratio" in section:
        lines += [
            "",
            "The same runs by CPU time (user + system, both cores together): "
            + _pairs(section, "_cpu"),
        ]
    return lines
