"""Render time at equal samples: each renderer against Principled BSDF at the main job's
scene, in A B, B A pairs (scripts/bench.py --only render)."""

import statistics
from pathlib import Path

from bench.common import MAIN_SCENE, RENDERERS, render


def bench_render(quick: bool, work: Path) -> dict:
    """Each renderer against Principled in pairs at the main job's scene, the pairs' order
    alternating; the median of the pairs' ratios (render time, and the whole process's wall
    time beside)."""
    scene = dict(MAIN_SCENE, size=256, samples=16) if quick else MAIN_SCENE
    pairs = 1 if quick else 3
    rows, ratios = [], {}
    for name in RENDERERS:
        if name == "principled":
            continue
        n = 1 if "eevee" in name else pairs  # EEVEE on a CPU is slow: one pair
        r_render, r_process = [], []
        for i in range(n):
            # A B, then B A: neither renderer always runs first
            order = [name, "principled"] if i % 2 == 0 else ["principled", name]
            done = {
                r: render(r, work / f"{r}-{name}-{i}".replace(" ", "_"), **scene) for r in order
            }
            a, b = done[name], done["principled"]
            rows += [done[r] for r in order]
            r_render.append(a["render_seconds"] / b["render_seconds"])
            r_process.append(a["process_seconds"] / b["process_seconds"])
            print(
                f"{name}: {a['render_seconds']:.2f} s / principled {b['render_seconds']:.2f} s",
                flush=True,
            )
        ratios[name] = {
            "render": round(statistics.median(r_render), 3),
            "process": round(statistics.median(r_process), 3),
            "pairs": n,
            "each_render": [round(r, 3) for r in r_render],
        }
    return {"scene": scene, "rows": rows, "ratios_over_principled": ratios}


def render_table(section: dict) -> list:
    sc = section["scene"]
    lines = [
        f"Scene: {sc['grid']} spheres, {sc['size']} px, {sc['samples']} samples, forest.exr "
        "(the main job's). Render time = Cycles' sync + render (scene.json); process = "
        "the whole `ctlab render` process. Ratio = median over pairs (A B, B A, A B; EEVEE "
        "one pair).",
        "",
        "| renderer | pairs | render / Principled | process / Principled | each pair |",
        "|---|---|---|---|---|",
    ]
    for name, r in section["ratios_over_principled"].items():
        each = ", ".join(f"{x:.2f}" for x in r["each_render"])
        lines.append(
            f"| {name} | {r['pairs']} | **{r['render']:.2f}x** | {r['process']:.2f}x | {each} |"
        )
    lines += ["", "| render | seconds (render) | sync | process |", "|---|---|---|---|"]
    for r in section["rows"]:
        sync = "–" if r["sync_seconds"] is None else f"{r['sync_seconds']:.2f}"
        lines.append(
            f"| {r['renderer']} | {r['render_seconds']:.2f} | {sync} | {r['process_seconds']:.2f} |"
        )
    return lines
