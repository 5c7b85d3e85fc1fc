"""Benchmarks, each figure a ratio measured in one run on this machine (described in the
results): render time against Principled BSDF at equal samples (A B A B pairs, the median of
the pairs' ratios), the equal-error study (each renderer's error against its own converged
image as a function of render time), the main job's wall time, and bake times.

Every render runs in its own process (scripts/ctlab.py render), as an artist's would: its
render time is Cycles' synchronisation plus render as scene.json records them, and the
process's wall time is reported beside it.

    ./scripts/dev.sh bench [--quick] [--only SECTION ...] [--pairs N] [--config NAME ...]
                           [--no-write]

Writes bench/results.json and bench/results.md (docs/testing.md, "Benchmark"). ``--only``
re-runs the named sections (render, error, main, bake, scene, graph, scene-real: every
material of a product shot converted, scene-cost: what each part of the converted group
costs there, scene-samples: the OSL correction's samples at equal error, scene-depth: the
correction's depth, its fidelity and time, and material-files: a converted material's sync
and .blend size) and keeps the others from results.json.
Each section is a module of bench/ (bench/__init__.py); this script is the benchmark's one
entry point: the options, which sections run, the results written, and the sections' child
processes (``--child SECTION ARGS``, bench/common.py ``child``). ``--pairs`` and ``--config``
go to the sections that take them (scene-real, scene-cost, scene-depth); ``--no-write``
prints the tables and leaves results.json and results.md as they are.
Converged images for the error study are cached in out/bench-cache (keyed by Blender's
version, the renderer, the scene and the model's sources).
"""

import argparse
import inspect
import json
import os
import platform
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
import bpy  # noqa: E402  (Blender as a module)
import numpy as np  # noqa: E402

import addon.blender  # noqa: E402,F401  (exposes Blender's bundled OpenImageIO)
from bench import (  # noqa: E402
    bake,
    equal_error,
    main_job,
    material_files,
    render_time,
    scene_cost,
    scene_depth,
    scene_real,
    scene_samples,
    scene_transport,
    task_graph,
)

OUT = ROOT / "bench"
SCHEMA = 2  # results.json's layout
# The sections, in the order they run and appear in results.md:
# name: (title in results.md, bench_<section>(quick, work) -> dict, <section>_table(dict) -> lines)
SECTIONS = {
    "render": (
        "Render time at equal samples",
        render_time.bench_render,
        render_time.render_table,
    ),
    "error": ("Equal error", equal_error.bench_error, equal_error.error_table),
    "main": ("The main job", main_job.bench_main, main_job.main_table),
    "bake": ("Bake (split-sum files)", bake.bench_bake, bake.bake_table),
    "scene": (
        "The scene transport in a real scene",
        scene_transport.bench_scene,
        scene_transport.scene_table,
    ),
    "graph": ("The main job as a task graph", task_graph.bench_graph, task_graph.graph_table),
    "scene-real": (
        "Every material of a product shot converted",
        scene_real.bench_scene_real,
        scene_real.scene_real_table,
    ),
    "scene-cost": (
        "Where the converted product shot's time goes",
        scene_cost.bench_scene_cost,
        scene_cost.scene_cost_table,
    ),
    "scene-samples": (
        "The OSL correction's samples per shading point, at equal error",
        scene_samples.bench_scene_samples,
        scene_samples.scene_samples_table,
    ),
    "scene-depth": (
        "The correction's depth: fidelity and time",
        scene_depth.bench_scene_depth,
        scene_depth.scene_depth_table,
    ),
    "material-files": (
        "A converted material's sync and file size",
        material_files.bench_material_files,
        material_files.material_files_table,
    ),
}


def machine() -> dict:
    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    try:
        pages = os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
        memory = round(pages / 2**30, 1)
    except (ValueError, OSError):
        memory = None
    return {
        "cpu": cpu,
        "cores": os.cpu_count(),
        "memory_gib": memory,
        "platform": platform.platform(),
        "python": platform.python_version(),
        "blender": bpy.app.version_string,
        "numpy": np.__version__,
        "device": "CPU (Cycles CPU; EEVEE on Mesa's software OpenGL)",
    }


# A section's child process: the hook its converted renders run after the conversion
CHILD_HOOKS = {
    "scene-real": None,
    "scene-cost": scene_cost.apply_variant,
    "scene-samples": scene_samples.with_samples,
    "scene-depth": scene_depth.with_depth,
}
# A section whose child process is its own (not a render of bench/scene_real.py's shot)
CHILD_MAINS = {"material-files": material_files.child_main}


def main():
    if sys.argv[1:2] == ["--child"]:
        if sys.argv[2] in CHILD_MAINS:
            CHILD_MAINS[sys.argv[2]](sys.argv[3:])
        scene_real.child_main(sys.argv[3:], CHILD_HOOKS[sys.argv[2]])
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true", help="smaller renders (a smoke run)")
    ap.add_argument(
        "--only",
        nargs="+",
        choices=list(SECTIONS),
        help="run these sections, keep the others from results.json",
    )
    ap.add_argument(
        "--pairs", type=int, help="A/B pairs (main, scene-real, scene-cost, scene-depth; default 2)"
    )
    ap.add_argument(
        "--config",
        nargs="+",
        choices=list(scene_real.CONFIGS),
        dest="configs",
        help="scene-real's configurations (default: all)",
    )
    ap.add_argument("--no-write", action="store_true", help="print the tables only")
    args = ap.parse_args()
    extra = {k: v for k, v in (("pairs", args.pairs), ("configs", args.configs)) if v is not None}
    results = {}
    if args.only and (OUT / "results.json").is_file():
        results = json.loads((OUT / "results.json").read_text())
        if results.get("schema") != SCHEMA:
            results = {}  # an older layout: its sections are not kept
    results["schema"] = SCHEMA
    results["machine"] = machine()
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        for section, (_title, run, _table) in SECTIONS.items():
            if args.only and section not in args.only:
                continue
            takes = inspect.signature(run).parameters
            options = {k: v for k, v in extra.items() if k in takes}
            results[section] = run(args.quick, work, **options)
            results[section]["machine"] = results["machine"]
    if not args.no_write:
        OUT.mkdir(exist_ok=True)
        (OUT / "results.json").write_text(json.dumps(results, indent=2))

    def described(m):
        return (
            f"Measured on {m['cpu']}, {m['cores']} cores, {m['memory_gib']} GiB, "
            f"{m['platform']}; Blender {m['blender']} (Python {m['python']}, numpy "
            f"{m['numpy']}); {m['device']}."
        )

    kept = {json.dumps(results[k]["machine"], sort_keys=True) for k in SECTIONS if k in results}
    lines = (
        [described(results["machine"]), ""]
        if len(kept) <= 1
        else ["Sections measured on different machines or versions: each says which.", ""]
    )
    if len(kept) > 1:
        for k in SECTIONS:
            if k in results:
                results[k]["note"] = described(results[k]["machine"])

    def head(title, key):
        note = results[key].get("note") if len(kept) > 1 else None
        return [f"### {title}", ""] + ([note, ""] if note else [])

    for section, (title, _run, table) in SECTIONS.items():
        if section in results:
            lines += head(title, section) + table(results[section]) + [""]
    if not args.no_write:
        (OUT / "results.md").write_text("\n".join(lines))
    print("\n".join(lines))


if __name__ == "__main__":
    main()
