"""The main job as a task graph: local workers, a farm projected (scripts/bench.py --only
graph)."""

import json
import subprocess
import sys
import time
from pathlib import Path

from bench.common import CTLAB

# A reduced main job (the full one, 3 runs of about 3 minutes on 2 cores, would not fit a
# session): the same 13 render tasks and merge, fewer pixels and samples.
GRAPH_SCENE = {"grid": "7x7", "size": 256, "samples": 16}
GRAPH_QUICK = {"grid": "2x2", "size": 48, "samples": 4}
# The main job's own setting (README), once with one worker: each task's overhead there.
GRAPH_MAIN = {"grid": "7x7", "size": 512, "samples": 64}
GRAPH_WORKERS = (1, 2, 4)
FARM_WORKERS = 100


def _graph_run(job: Path, scene: dict, workers: int) -> dict:
    """Plan, run the render tasks as ``workers`` local ``ctlab task`` processes (a farm's
    view: every task its own process), then merge; each task's wall time and its split."""
    from addon.core import jobgraph

    opts = [
        "--grid",
        scene["grid"],
        "--size",
        str(scene["size"]),
        "--samples",
        str(scene["samples"]),
    ]
    start = time.perf_counter()
    subprocess.run(
        [sys.executable, str(CTLAB), "plan", "matrix", *opts, "--out", str(job)],
        check=True,
        capture_output=True,
    )
    plan = jobgraph.read_plan(job)
    pending, running, walls = list(jobgraph.render_tasks(plan)), {}, {}
    while pending or running:
        while pending and len(running) < workers:
            t = pending.pop(0)
            proc = subprocess.Popen(
                [sys.executable, str(CTLAB), "task", str(job), t["id"]],
                stdout=subprocess.DEVNULL,
                stderr=subprocess.PIPE,
            )
            running[proc] = (t, time.perf_counter())
        time.sleep(0.05)
        for proc in [p for p in running if p.poll() is not None]:
            t, t0 = running.pop(proc)
            if proc.returncode:
                raise SystemExit(f"bench: task {t['id']} failed:\n{proc.stderr.read()[-2000:]}")
            walls[t["folder"]] = time.perf_counter() - t0
    t0 = time.perf_counter()
    subprocess.run([sys.executable, str(CTLAB), "merge", str(job)], check=True, capture_output=True)
    merge = time.perf_counter() - t0
    tasks = []
    for t in jobgraph.render_tasks(plan):
        info = json.loads(jobgraph.marker_path(job, t).read_text())["info"]
        wall = walls[t["folder"]]
        start_up = info.get("process_start_seconds") or 0.0
        build = info["task_seconds"] - (info.get("render_seconds") or 0.0)
        sync = info.get("sync_seconds") or 0.0
        overhead = start_up + build + sync
        tasks.append(
            {
                "task": t["folder"],
                "wall_seconds": round(wall, 2),
                "process_start_seconds": round(start_up, 2),
                "build_and_save_seconds": round(build, 2),
                "sync_seconds": round(sync, 2),
                "cycles_render_seconds": info.get("cycles_render_seconds"),
                "exit_seconds": round(wall - start_up - info["task_seconds"], 2),
                "overhead_fraction": round(overhead / wall, 3),
            }
        )
    return {
        "workers": workers,
        "makespan_seconds": round(time.perf_counter() - start, 1),
        "merge_seconds": round(merge, 1),
        "tasks": tasks,
    }


def bench_graph(quick: bool, work: Path) -> dict:
    """The main job's task graph at 1, 2 and 4 local workers (makespan: plan to report),
    each task's time and overhead (process start, scene build and saving, Cycles'
    synchronisation = the shader compile), and a projection for a 100-worker farm: the
    critical path (the longest render task, then the merge) against the work spread over
    the workers, max(critical path, total / workers) + the merge."""
    scene = GRAPH_QUICK if quick else GRAPH_SCENE
    runs = []
    subprocess.run(
        [sys.executable, str(CTLAB), "bake", str(_forest())], check=True, capture_output=True
    )  # the bake cached, as after set-up
    for workers in GRAPH_WORKERS:
        runs.append(_graph_run(work / f"graph-{workers}", scene, workers))
        print(f"graph, {workers} workers: {runs[-1]['makespan_seconds']} s", flush=True)
    one = runs[0]
    walls = [t["wall_seconds"] for t in one["tasks"]]
    total = sum(walls)
    over = [t["overhead_fraction"] for t in one["tasks"]]
    farm = round(max(max(walls), total / FARM_WORKERS) + one["merge_seconds"], 1)
    main = None
    if not quick:  # the same tasks at the main job's own setting, one worker
        main = _graph_run(work / "graph-main", GRAPH_MAIN, 1)
        print(f"graph at the main job's setting: {main['makespan_seconds']} s", flush=True)
        main["single_process_seconds"] = _single_process(work / "single-main", GRAPH_MAIN)
        main["graph_over_single"] = round(
            main["makespan_seconds"] / main["single_process_seconds"], 3
        )
        main_over = [t["overhead_fraction"] for t in main["tasks"]]
        main["overhead_fraction_mean"] = round(sum(main_over) / len(main_over), 3)
        main["overhead_fraction_max"] = round(max(main_over), 3)
        main["scene"] = GRAPH_MAIN
    return {
        "scene": scene,
        "main_setting": main,
        "runs": runs,
        "farm_workers": FARM_WORKERS,
        "farm_projection_seconds": farm,
        "critical_path_seconds": round(max(walls) + one["merge_seconds"], 1),
        "total_task_seconds": round(total, 1),
        "overhead_fraction_mean": round(sum(over) / len(over), 3),
        "overhead_fraction_max": round(max(over), 3),
    }


def _single_process(out: Path, scene: dict) -> float:
    """`ctlab matrix` as one process at ``scene``: its wall time (plan to report)."""
    opts = ["--grid", scene["grid"], "--size", str(scene["size"]), "--samples"]
    start = time.perf_counter()
    subprocess.run(
        [sys.executable, str(CTLAB), "matrix", *opts, str(scene["samples"]), "--out", str(out)],
        check=True,
        capture_output=True,
    )
    return round(time.perf_counter() - start, 1)


def _forest() -> Path:
    from addon.blender.paths import bundled_hdri

    return bundled_hdri("forest")


def graph_table(section: dict) -> list:
    sc = section["scene"]
    lines = [
        f"The main job's task graph (13 render tasks, then the merge: comparisons, 4 BRDF "
        f"plots, the report) at a reduced setting: grid {sc['grid']}, {sc['size']} px, "
        f"{sc['samples']} samples; every task its own `ctlab task` process; makespan = "
        "plan to report.",
        "",
        "| local workers | makespan (s) | merge (s) |",
        "|---|---|---|",
    ]
    for r in section["runs"]:
        lines.append(f"| {r['workers']} | {r['makespan_seconds']:.1f} | {r['merge_seconds']:.1f} |")
    lines += [
        "",
        "Each task (1 worker): wall = process start + scene build and saving + Cycles "
        "sync (shader compile) + Cycles render + exit.",
        "",
        "| task | wall (s) | process start | build + save | sync | render | overhead |",
        "|---|---|---|---|---|---|---|",
    ]
    lines += _task_rows(section["runs"][0]["tasks"])
    lines += [
        "",
        f"Overhead fraction of a task: mean "
        f"{100 * section['overhead_fraction_mean']:.0f}%, max "
        f"{100 * section['overhead_fraction_max']:.0f}% (at this reduced setting; "
        "the render part grows with pixels x samples, the overhead does not).",
        f"Projection for {section['farm_workers']} farm workers (critical path: the "
        f"longest task, then the merge; total task time "
        f"{section['total_task_seconds']} s): **{section['farm_projection_seconds']} s**.",
    ]
    main = section.get("main_setting")
    if main:
        sc = main["scene"]
        lines += [
            "",
            f"The same tasks at the main job's own setting (grid {sc['grid']}, {sc['size']} "
            f"px, {sc['samples']} samples), one worker: makespan {main['makespan_seconds']:.1f} s "
            f"(merge {main['merge_seconds']:.1f} s), against {main['single_process_seconds']:.1f}"
            f" s for `ctlab matrix` as one process at that setting in the same run: the task "
            f"graph costs **{100 * (main['graph_over_single'] - 1):.0f}%** more.",
            "",
            "| task | wall (s) | process start | build + save | sync | render | overhead |",
            "|---|---|---|---|---|---|---|",
            *_task_rows(main["tasks"]),
            "",
            f"Overhead fraction of a task at the main job's setting: mean "
            f"**{100 * main['overhead_fraction_mean']:.0f}%**, max "
            f"{100 * main['overhead_fraction_max']:.0f}% (process start, scene build and "
            "saving, and Cycles' synchronisation, which a single process pays for each "
            "render too; the graph's own part, process start and exit, "
            f"{100 * _own_fraction(main['tasks']):.0f}% of the tasks' time).",
        ]
    return lines


def _own_fraction(tasks: list) -> float:
    own = sum(t["process_start_seconds"] + t["exit_seconds"] for t in tasks)
    return own / sum(t["wall_seconds"] for t in tasks)


def _task_rows(tasks: list) -> list:
    return [
        f"| {t['task']} | {t['wall_seconds']:.2f} | "
        f"{t['process_start_seconds']:.2f} | {t['build_and_save_seconds']:.2f} | "
        f"{t['sync_seconds']:.2f} | {t['cycles_render_seconds'] or 0:.2f} | "
        f"{100 * t['overhead_fraction']:.0f}% |"
        for t in tasks
    ]
