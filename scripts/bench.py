"""Benchmarks, each figure a ratio measured in one run on this machine (described in the
results): render time against Principled BSDF at equal samples (A B A B pairs, the median of
the pairs' ratios), the equal-error study (each renderer's error against its own converged
image as a function of render time), the main job's wall time, and bake times.

Every render runs in its own process (scripts/ctlab.py render), as an artist's would: its
render time is Cycles' synchronisation plus render as scene.json records them, and the
process's wall time is reported beside it.

    .venv-bpy<series>/bin/python scripts/bench.py [--quick] [--only SECTION ...]

Writes bench/results.json and bench/results.md (docs/testing.md, "Benchmark"). ``--only``
re-runs the named sections (render, error, main, bake, scene, graph, and scene-real: every
material of a product shot converted, bench/scene_real.py) and keeps the others from
results.json.
Converged images for the error study are cached in out/bench-cache (keyed by Blender's
version, the renderer, the scene and the model's sources).
"""

import argparse
import functools
import hashlib
import json
import os
import platform
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
import bpy  # noqa: E402  (Blender as a module)
import numpy as np  # noqa: E402

import addon.blender  # noqa: E402,F401  (exposes Blender's bundled OpenImageIO)
from addon.core.compare import cell_mask, ciede2000, load_render, srgb_to_lab  # noqa: E402
from addon.core.files import atomic_folder  # noqa: E402

OUT = ROOT / "bench"
CACHE = ROOT / "out" / "bench-cache"
CTLAB = ROOT / "scripts" / "ctlab.py"
BUNDLED = ("city", "courtyard", "forest", "interior", "night", "studio", "sunrise", "sunset")
SECTIONS = ("render", "error", "main", "bake", "scene", "graph", "scene-real")
SCHEMA = 2  # results.json's layout

# The renderers, as ctlab render's arguments; Principled is every ratio's denominator.
RENDERERS = {
    "principled": ["--shader", "principled"],
    "osl reference": ["--shader", "osl", "--ibl", "reference"],
    "osl split_sum": ["--shader", "osl", "--ibl", "split_sum"],
    "osl unity": ["--shader", "osl", "--ibl", "unity"],
    "nodes split_sum": ["--shader", "nodes", "--ibl", "split_sum"],
    "nodes split_sum (eevee)": ["--shader", "nodes", "--ibl", "split_sum", "--engine", "eevee"],
}
# The reference integrator's samples per shading point (each of BSDF and environment
# sampling; the default is 4), in the equal-error study only, against the converged image
# of the renderer they vary.
ENV_VARIANTS = {
    f"osl reference (env {n})": RENDERERS["osl reference"] + ["--env-samples", str(n)]
    for n in (1, 2, 8)
}
CONVERGED_AS = dict.fromkeys(ENV_VARIANTS, "osl reference")
ARGS = {**RENDERERS, **ENV_VARIANTS}
MAIN_SCENE = {"grid": "7x7", "size": 512, "samples": 64}  # the main job's defaults


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


def render(name: str, out: Path, grid: str, size: int, samples: int, seed: int = 0) -> dict:
    """One render of the sphere matrix in a child process: its times and folder."""
    cmd = [
        sys.executable,
        str(CTLAB),
        "render",
        *ARGS[name],
        "--grid",
        grid,
        "--size",
        str(size),
        "--samples",
        str(samples),
        "--seed",
        str(seed),
        "--out",
        str(out),
    ]
    start = time.perf_counter()
    done = subprocess.run(cmd, capture_output=True, text=True)
    wall = time.perf_counter() - start
    if done.returncode != 0:
        raise SystemExit(f"bench: {' '.join(cmd)} failed:\n{done.stderr[-2000:]}")
    scene = json.loads((out / "scene.json").read_text())
    if scene.get("cycles_render_seconds") is not None:
        seconds = scene["sync_seconds"] + scene["cycles_render_seconds"]
    else:  # EEVEE records no timings: the render call's wall time
        seconds = scene["render_seconds"]
    return {
        "renderer": name,
        "grid": grid,
        "size": size,
        "samples": samples,
        "seed": seed,
        "sync_seconds": scene.get("sync_seconds"),
        "render_seconds": round(seconds, 3),
        "process_seconds": round(wall, 2),
        "folder": str(out),
    }


# --- Render time at equal samples ---------------------------------------------------------


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


# --- Equal error ---------------------------------------------------------------------------

CLASSES = {
    "smooth metal": lambda m, s: m >= 0.5 and s >= 0.5,
    "rough metal": lambda m, s: m >= 0.5 and s < 0.5,
    "smooth dielectric": lambda m, s: m < 0.5 and s >= 0.5,
    "rough dielectric": lambda m, s: m < 0.5 and s < 0.5,
}


@functools.cache
def _sources_digest() -> str:
    h = hashlib.sha256()
    for p in (
        sorted((ROOT / "osl").glob("*.[oh]*"))
        + sorted((ROOT / "node_groups").glob("*.toml"))
        + sorted((ROOT / "addon").rglob("*.py"))
    ):
        h.update(p.read_bytes())
    return h.hexdigest()[:12]


def converged(name: str, grid: str, size: int, samples: int) -> Path:
    """The renderer's own converged image (seed 1), cached across runs."""
    key = f"{bpy.app.version_string}-{name}-{grid}-{size}-{samples}-{_sources_digest()}"
    folder = CACHE / key.replace(" ", "_").replace("(", "").replace(")", "")
    if not (folder / "scene.json").is_file():
        shutil.rmtree(folder, ignore_errors=True)

        def fill(stage):
            row = render(name, stage, grid, size, samples, seed=1)
            print(f"converged {name}: {samples} samples, {row['render_seconds']:.1f} s", flush=True)

        atomic_folder(folder, fill)
    return folder


def errors(folder: Path, reference: Path) -> dict:
    """RMSE of the displayed image (sRGB, 0..1) and mean CIEDE2000 against the converged
    image, over the spheres of each class. Displayed, not linear: a sun's glint on a mirror
    sphere covers a pixel at radiance in the thousands, and the linear RMSE of the smooth
    metals is that one pixel's luck, not the noise a viewer sees."""
    lin, disp, scene = load_render(folder)
    lin_r, disp_r, _ = load_render(reference)
    de = ciede2000(srgb_to_lab(disp), srgb_to_lab(disp_r))
    out = {}
    for cls, test in CLASSES.items():
        mask = np.zeros(lin.shape[:2], dtype=bool)
        for cell in scene["cells"]:
            if test(cell["metallic"], cell["smoothness"]):
                mask |= cell_mask(lin.shape, cell)
        d = (disp[mask] - disp_r[mask]).astype(np.float64)
        out[cls] = {"rmse": float(np.sqrt(np.mean(d**2))), "mean_de": float(de[mask].mean())}
    return out


def bench_error(quick: bool, work: Path) -> dict:
    """Each Cycles renderer at 8..128 samples against its own converged image (1024 samples,
    another seed). Monte Carlo error falls as 1/sqrt(time), so RMSE x sqrt(render time) is a
    renderer's cost constant per class; the time to reach an equal error, over Principled's,
    is the square of the ratio of those constants, taken at the highest sample count (where
    the fixed sync cost weighs least). The converged image's own noise (1/8 of the error's
    variance at 128 samples) is left in: it flatters no renderer. The reference integrator
    is also measured with 1, 2 and 8 samples per shading point against the same converged
    image (its default is 4); that image's own noise then weighs more against the less noisy
    variants, so 8 samples is, if anything, flattered less than 1."""
    grid, size = "7x7", 256
    counts = (8, 32) if quick else (8, 16, 32, 64, 128)
    ref_samples = 256 if quick else 1024
    names = [n for n in RENDERERS if "eevee" not in n] + ([] if quick else list(ENV_VARIANTS))
    series = {}
    for name in names:
        ref = converged(CONVERGED_AS.get(name, name), grid, size, ref_samples)
        rows = []
        for n in counts:
            r = render(name, work / f"err-{name}-{n}".replace(" ", "_"), grid, size, n)
            rows.append(
                {
                    "samples": n,
                    "render_seconds": r["render_seconds"],
                    "errors": errors(Path(r["folder"]), ref),
                }
            )
            shutil.rmtree(r["folder"])
        series[name] = rows
        print(
            f"error series {name}: "
            + ", ".join(f"{row['samples']}spp {row['render_seconds']:.1f}s" for row in rows),
            flush=True,
        )
    equal_error = {}
    for name in names:
        last, base = series[name][-1], series["principled"][-1]
        equal_error[name] = {}
        for cls in CLASSES:
            k = last["errors"][cls]["rmse"] * last["render_seconds"] ** 0.5
            k0 = base["errors"][cls]["rmse"] * base["render_seconds"] ** 0.5
            equal_error[name][cls] = round((k / k0) ** 2, 3)
    return {
        "scene": {
            "grid": grid,
            "size": size,
            "converged_samples": ref_samples,
            "samples": list(counts),
        },
        "series": series,
        "time_at_equal_rmse_over_principled": equal_error,
    }


def error_table(section: dict) -> list:
    sc = section["scene"]
    lines = [
        f"Scene: {sc['grid']} spheres, {sc['size']} px, forest.exr; each renderer against "
        f"its own converged image ({sc['converged_samples']} samples, another seed). "
        "Time to reach the same RMSE as Principled, over Principled's (from RMSE x "
        "sqrt(render time) at the highest sample count):",
        "",
        "| renderer | " + " | ".join(CLASSES) + " |",
        "|---|" + "---|" * len(CLASSES),
    ]
    for name, by in section["time_at_equal_rmse_over_principled"].items():
        lines.append(f"| {name} | " + " | ".join(f"{by[c]:.3f}x" for c in CLASSES) + " |")
    lines += [
        "",
        "RMSE (displayed sRGB) and mean CIEDE2000 against the converged image, by samples "
        "(render seconds):",
        "",
        "| renderer | samples | seconds | " + " | ".join(f"{c} RMSE / ΔE" for c in CLASSES) + " |",
        "|---|---|---|" + "---|" * len(CLASSES),
    ]
    for name, rows in section["series"].items():
        for row in rows:
            cells = " | ".join(
                f"{row['errors'][c]['rmse']:.4f} / {row['errors'][c]['mean_de']:.2f}"
                for c in CLASSES
            )
            lines.append(f"| {name} | {row['samples']} | {row['render_seconds']:.2f} | {cells} |")
    return lines


# --- The main job ------------------------------------------------------------------------


def bench_main(work: Path) -> dict:
    """`ctlab matrix` at its defaults, the whole process, in an empty output folder (the
    split-sum bake cached, as after any earlier run)."""
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


# --- The main job as a task graph: local workers, a farm projected --------------------

# A reduced main job (the full one, 3 runs of about 3 minutes on 2 cores, would not fit a
# session): the same 13 render tasks and merge, fewer pixels and samples.
GRAPH_SCENE = {"grid": "7x7", "size": 256, "samples": 16}
GRAPH_QUICK = {"grid": "2x2", "size": 48, "samples": 4}
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
    return {
        "scene": scene,
        "runs": runs,
        "farm_workers": FARM_WORKERS,
        "farm_projection_seconds": farm,
        "critical_path_seconds": round(max(walls) + one["merge_seconds"], 1),
        "total_task_seconds": round(total, 1),
        "overhead_fraction_mean": round(sum(over) / len(over), 3),
        "overhead_fraction_max": round(max(over), 3),
    }


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
    for t in section["runs"][0]["tasks"]:
        lines.append(
            f"| {t['task']} | {t['wall_seconds']:.2f} | "
            f"{t['process_start_seconds']:.2f} | {t['build_and_save_seconds']:.2f} | "
            f"{t['sync_seconds']:.2f} | {t['cycles_render_seconds'] or 0:.2f} | "
            f"{100 * t['overhead_fraction']:.0f}% |"
        )
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
    return lines


# --- Bake times --------------------------------------------------------------------------


def synthetic_hdri(path: Path, width: int) -> None:
    """A smooth sky-and-ground gradient with a small sun of radiance 2000."""
    import numpy as np
    from addon.core.hdri import write_float_exr

    h = width // 2
    e = (0.5 - (np.arange(h) + 0.5) / h)[:, None] * np.pi
    s = (np.arange(width) + 0.5)[None, :] / width
    sky = np.where(e > 0, 0.6 + 0.4 * np.sin(e), 0.2 + 0.05 * np.cos(8 * np.pi * s))
    img = np.repeat(sky[:, :, None], 3, axis=2).astype(np.float32) * np.array(
        [0.9, 1.0, 1.1], dtype=np.float32
    )
    r = max(1, width // 512)
    img[h // 4 - r : h // 4 + r, width // 3 - r : width // 3 + r] = 2000.0
    write_float_exr(path, img)


def bench_bake() -> dict:
    """Each HDRI baked into an empty cache (the first bake an artist waits for; the DFG tables
    ship with the extension) and again (cached)."""
    from addon.core import ibl_bake
    from addon.blender.paths import bundled_hdri

    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        inputs = [(name, bundled_hdri(name)) for name in BUNDLED]
        for width in (2048, 4096):
            path = tmp / f"synthetic-{width}.exr"
            synthetic_hdri(path, width)
            inputs.append((f"synthetic {width}x{width // 2}", path))
        for i, (name, path) in enumerate(inputs):
            os.environ["CTLAB_CACHE"] = str(tmp / f"cache-{i}")  # empty
            t = time.perf_counter()
            folder = ibl_bake.bake(path)
            cold = time.perf_counter() - t
            t = time.perf_counter()
            ibl_bake.bake(path)
            cached = time.perf_counter() - t
            info = json.loads((folder / ibl_bake.INFO_FILE).read_text())
            w, h = info["source_size"]
            rows.append(
                {
                    "hdri": name,
                    "size": f"{w}x{h}",
                    "megapixels": round(w * h / 1e6, 3),
                    "bake_seconds": round(cold, 3),
                    "cached_seconds": round(cached, 4),
                    "stages": info["timings"],
                }
            )
            print(rows[-1], flush=True)
    one_k = [r["bake_seconds"] - r["cached_seconds"] for r in rows if r["size"] == "1024x512"]
    return {
        "rows": rows,
        "bundled_1k_first_over_cached_mean_seconds": round(sum(one_k) / len(one_k), 3),
        "bundled_1k_first_over_cached_max_seconds": round(max(one_k), 3),
    }


def bake_table(section: dict) -> list:
    lines = [
        "| HDRI | size | bake (s) | cached (s) | level 1 (s) | level 0 copy (s) |",
        "|---|---|---|---|---|---|",
    ]
    for r in section["rows"]:
        st = r["stages"]
        lines.append(
            f"| {r['hdri']} | {r['size']} | {r['bake_seconds']:.2f} | "
            f"{r['cached_seconds']:.3f} | {st['specular_1.exr']:.2f} | "
            f"{st['specular_0.exr']:.2f} |"
        )
    return lines + [
        "",
        "Bundled 1024x512 HDRIs, a first bake in an empty cache over a cached "
        f"one: mean {section['bundled_1k_first_over_cached_mean_seconds']} s, "
        f"max {section['bundled_1k_first_over_cached_max_seconds']} s.",
    ]


# --- The scene transport in a real scene -------------------------------------------------

# The sphere's material in the demo scene (addon/blender/demo_scene.py): Principled BSDF (the
# denominator), and the model's scene transport with exact closures, with the correction, and
# as the node group.
# Each: (Cycles' shading system, the model's implementation or None for Principled, options).
# An OSL material turns Cycles' OSL shading on for the whole scene, so Principled is measured
# on both systems: the material's own cost is the ratio at the same shading system.
SCENE_VARIANTS = {
    "principled": ("svm", None, {}),
    "principled (osl shading)": ("osl", None, {}),
    "osl scene (exact closures)": (
        "osl",
        "osl",
        {"g_model": "smith_ggx_correlated", "diffuse_model": "lambert"},
    ),
    "osl scene (correction)": (
        "osl",
        "osl",
        {"g_model": "cook_torrance", "diffuse_model": "disney"},
    ),
    "nodes scene": (
        "svm",
        "nodes",
        {"g_model": "smith_ggx_correlated", "diffuse_model": "lambert", "ibl": "split_sum"},
    ),
}
SAME_SYSTEM = {"osl": "principled (osl shading)", "svm": "principled"}


def bench_scene(quick: bool, work: Path) -> dict:
    """Render time of the demo scene (a metal sphere and an orange sphere beside a cube, a
    floor, an area light, an emissive panel, forest.exr) with each material for both spheres,
    against Principled, in one process: each variant warmed up once (the OSL shader's
    compilation), then rounds in alternating order; ratio = the median over rounds. Also the
    world bake of a Sky Texture when the add-on has it."""
    from addon.blender import demo_scene, light_sync, materials, renderer
    from addon.core.model import ModelOptions

    size, samples, rounds = ((128, 96), 16, 1) if quick else ((320, 240), 64, 4)
    scene, sphere, other = demo_scene.build("hdri", *size)
    mats = {}
    for name, (_system, impl, model) in SCENE_VARIANTS.items():
        pair = []
        for obj, values, label in (
            (sphere, demo_scene.METAL, "metal"),
            (other, demo_scene.ORANGE, "orange"),
        ):
            if impl is None:
                pair.append(demo_scene.principled_for(values, f"{name} {label}"))
            else:
                mat = materials.model_material(
                    f"{name} {label}",
                    impl,
                    ModelOptions(light_transport="scene", **model),
                    **values,
                )
                demo_scene.set_material(obj, mat)
                light_sync.sync_material(mat, scene)
                pair.append(mat)
        mats[name] = pair

    def timed(name, samples_):
        demo_scene.set_material(sphere, mats[name][0])
        demo_scene.set_material(other, mats[name][1])
        system, impl, _model = SCENE_VARIANTS[name]
        shader = "osl" if system == "osl" else (impl or "principled")
        renderer.configure(scene, shader, "full", samples_, path_traced=True)
        d = renderer.render(
            scene, work / f"scene-{len(os.listdir(work))}", {"width": size[0], "height": size[1]}
        )
        return d["sync_seconds"] + d["cycles_render_seconds"]

    for name in SCENE_VARIANTS:
        timed(name, 1)  # warm-up: compile, load, build
    times = {name: [] for name in SCENE_VARIANTS}
    names = list(SCENE_VARIANTS)
    for i in range(rounds):
        for name in names if i % 2 == 0 else names[::-1]:
            times[name].append(timed(name, samples))
            print(f"scene: {name}: {times[name][-1]:.2f} s", flush=True)

    def ratio(name, over):
        return round(statistics.median(times[name]) / statistics.median(times[over]), 3)

    out = {
        "scene": {
            "size": list(size),
            "samples": samples,
            "rounds": rounds,
            "objects": "metal sphere + orange sphere (both the material timed) + red "
            "cube + floor + area light + emissive panel, forest.exr",
        },
        "seconds": {k: [round(t, 3) for t in v] for k, v in times.items()},
        "ratio_over_principled": {k: ratio(k, "principled") for k in times if k != "principled"},
        "ratio_same_shading": {
            k: ratio(k, SAME_SYSTEM[v[0]]) for k, v in SCENE_VARIANTS.items() if v[1] is not None
        },
    }
    try:
        from addon.blender import world_bake
    except ImportError:
        world_bake = None
    if world_bake is not None:
        demo_scene.build("sky", 64, 48)
        saved = os.environ.get("CTLAB_CACHE")
        with tempfile.TemporaryDirectory() as empty:  # cold: nothing cached
            os.environ["CTLAB_CACHE"] = empty
            try:
                start = time.perf_counter()
                world_bake.bake_world(bpy.context.scene.world, 1024)
                out["sky_bake_seconds_1k"] = round(time.perf_counter() - start, 2)
            finally:
                if saved is None:
                    os.environ.pop("CTLAB_CACHE", None)
                else:
                    os.environ["CTLAB_CACHE"] = saved
    return out


def scene_table(section: dict) -> list:
    sc = section["scene"]
    lines = [
        f"The demo scene ({sc['objects']}), {sc['size'][0]}x{sc['size'][1]} px, "
        f"{sc['samples']} samples, Cycles CPU, one process; render = Cycles' sync + "
        f"render; ratio = median over {sc['rounds']} alternating rounds.",
        "",
        "| the spheres' material | seconds | / Principled (SVM) | / Principled, same "
        "shading system |",
        "|---|---|---|---|",
    ]
    for name, secs in section["seconds"].items():
        ratio = section["ratio_over_principled"].get(name)
        same = section["ratio_same_shading"].get(name)
        lines.append(
            f"| {name} | {', '.join(f'{t:.2f}' for t in secs)} | "
            + ("1" if ratio is None else f"{ratio:.2f}x")
            + " | "
            + ("–" if same is None else f"**{same:.2f}x**")
            + " |"
        )
    if "sky_bake_seconds_1k" in section:
        lines += [
            "",
            f"World bake of a Sky Texture at 1024x512: "
            f"**{section['sky_bake_seconds_1k']:.2f} s** (cold).",
        ]
    return lines


def _scene_real():
    """bench/scene_real.py (its own module: the product shot, every material converted)."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("scene_real", OUT / "scene_real.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true", help="smaller renders (a smoke run)")
    ap.add_argument(
        "--only",
        nargs="+",
        choices=SECTIONS,
        help="run these sections, keep the others from results.json",
    )
    args = ap.parse_args()
    results = {}
    if args.only and (OUT / "results.json").is_file():
        results = json.loads((OUT / "results.json").read_text())
        if results.get("schema") != SCHEMA:
            results = {}  # an older layout: its sections are not kept
    results["schema"] = SCHEMA
    results["machine"] = machine()
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        for section in SECTIONS:
            if args.only and section not in args.only:
                continue
            if section == "render":
                results["render"] = bench_render(args.quick, work)
            elif section == "error":
                results["error"] = bench_error(args.quick, work)
            elif section == "main":
                results["main"] = bench_main(work)
            elif section == "scene":
                results["scene"] = bench_scene(args.quick, work)
            elif section == "graph":
                results["graph"] = bench_graph(args.quick, work)
            elif section == "scene-real":
                results["scene-real"] = _scene_real().bench_scene_real(args.quick, work)
            else:
                results["bake"] = bench_bake()
            results[section]["machine"] = results["machine"]
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

    if "render" in results:
        lines += (
            head("Render time at equal samples", "render") + render_table(results["render"]) + [""]
        )
    if "error" in results:
        lines += head("Equal error", "error") + error_table(results["error"]) + [""]
    if "main" in results:
        lines += head("The main job", "main") + [
            f"`{results['main']['command']}` at its defaults: "
            f"**{results['main']['wall_seconds']:.0f} s** wall (the whole process).",
            "",
        ]
    if "bake" in results:
        lines += head("Bake (split-sum files)", "bake") + bake_table(results["bake"]) + [""]
    if "scene" in results:
        lines += (
            head("The scene transport in a real scene", "scene")
            + scene_table(results["scene"])
            + [""]
        )
    if "graph" in results:
        lines += (
            head("The main job as a task graph", "graph") + graph_table(results["graph"]) + [""]
        )
    if "scene-real" in results:
        lines += (
            head("Every material of a product shot converted", "scene-real")
            + _scene_real().scene_real_table(results["scene-real"])
            + [""]
        )
    (OUT / "results.md").write_text("\n".join(lines))
    print("\n".join(lines))


if __name__ == "__main__":
    main()
