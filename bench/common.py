"""What the benchmark's sections share: the repository's paths, the renderers as ``ctlab
render``'s arguments, and one render of the sphere matrix in its own process (as an artist's
would run it: its render time is Cycles' synchronisation plus render as scene.json records
them, and the process's wall time is reported beside it); a section's own child process
(``child``: scripts/bench.py --child SECTION ARGS, the one child entry of the benchmark); and
the one way they all run a child, timed by wall and CPU time (``timed_run``)."""

import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
# Converged images, bakes and the node group, kept across runs (keyed by their sources)
CACHE = ROOT / "out" / "bench-cache"
CTLAB = ROOT / "scripts" / "ctlab.py"
BENCH = ROOT / "scripts" / "bench.py"

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
ARGS = {**RENDERERS, **ENV_VARIANTS}
MAIN_SCENE = {"grid": "7x7", "size": 512, "samples": 64}  # the main job's defaults


def _cpu_of_children() -> float:
    """User + system CPU seconds of every child process waited for so far."""
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def timed_run(cmd: list, **kwargs) -> tuple:
    """``cmd`` run to its end (subprocess.run, output captured as text; ``kwargs`` passed on):
    the completed process, its wall time and its CPU time (user + system, its threads
    together) in seconds. Where other work shares the machine, the wall time grows with the
    waits; the CPU time counts only the process's own work."""
    cpu = _cpu_of_children()
    start = time.perf_counter()
    done = subprocess.run(cmd, capture_output=True, text=True, **kwargs)
    wall = time.perf_counter() - start
    return done, wall, _cpu_of_children() - cpu


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
    done, wall, _ = timed_run(cmd)
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


def child(section: str, *args) -> dict:
    """One child process of ``section`` (``scripts/bench.py --child SECTION ARGS``, which runs
    bench/scene_real.py's ``child_main`` with the section's hook): its RESULT line, with its
    wall time."""
    cmd = [sys.executable, str(BENCH), "--child", section, *map(str, args)]
    env = dict(os.environ)
    env.setdefault("CTLAB_CACHE", str(CACHE))
    # the child ends with os._exit (no atexit): its temporary folder, Blender's session folder
    # in it, is one of ours, removed here
    with tempfile.TemporaryDirectory(prefix="ctlab-bench-") as tmp:
        p, wall, _ = timed_run(cmd, env=dict(env, TMPDIR=tmp))
    if p.returncode != 0:
        raise SystemExit(f"bench: {' '.join(cmd)} failed:\n{(p.stderr or p.stdout)[-3000:]}")
    lines = [ln for ln in p.stdout.splitlines() if ln.startswith("RESULT ")]
    out = json.loads(lines[-1][7:]) if lines else {}
    out["process_seconds"] = round(wall, 2)
    return out
