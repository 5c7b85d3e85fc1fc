"""The batch jobs (the main matrix job, the Principled-parity job) as task graphs
(core/jobgraph/): one render task per render folder, then a merge that compares, plots and
writes the report reading only the job folder (jobs/graph_merge.py). ``ctlab plan`` writes
the graph, ``ctlab task`` runs one task, ``ctlab merge`` the merge; ``ctlab matrix`` runs the
same graph in this process (``run_graph``), or its render tasks as ``--workers N`` local
processes (jobs/workers.py).

A task rebuilds its settings from the plan's spec with this version's code and checks that
they give its id again (core.jobgraph.plan.content_id): a plan from another version, or edited
settings, is refused in one line rather than rendered into the wrong folder.
"""

from __future__ import annotations

import os
import sys
import time
import tomllib
from pathlib import Path

import bpy

from . import graph_merge, pipeline, plot_job
from .workers import describe_task, run_workers
from ..blender import renderer
from ..blender.paths import resolve_hdri
from ..core import ibl_bake, jobgraph
from ..core.errors import UserError
from ..core.files import PACKAGE_ROOT, check_writable, sha256
from ..core.hdri import file_hash, load_hdri
from ..core.paths import input_file
from ..core.settings import MatrixSettings, settings_from_dict, settings_to_dict

JOBS = ("matrix", "parity")


def ctlab_version() -> str:
    try:
        with open(PACKAGE_ROOT / "blender_manifest.toml", "rb") as f:
            return str(tomllib.load(f).get("version", "?"))
    except (OSError, tomllib.TOMLDecodeError):
        return "?"


def environment() -> dict:
    """What every task id includes besides its settings: the versions that change a render."""
    return {
        "ctlab": ctlab_version(),
        "ibl_tables": ibl_bake.VERSION,
        "plan": jobgraph.PLAN_VERSION,
        "blender": bpy.app.version_string,
    }


# ----------------------------------------------------------------------------------------
# The jobs' render folders, from their spec


def renders_of(job: str, spec: dict) -> dict:
    """{folder: settings} of a job's render tasks, in the order the job runs them. A spec
    whose values this version cannot build settings from (a plan edited by hand) is one
    UserError line."""
    if job not in JOBS:
        raise UserError(f"unknown job {job!r} in the plan; this ctlab plans: {', '.join(JOBS)}")
    try:
        base = settings_from_dict(spec["base"])
        if job == "matrix":
            return pipeline.matrix_settings(base)
        out = {}
        for name, ct, pr in pipeline.parity_runs(
            base, [Path(h) for h in spec["hdris"]], spec.get("name")
        ):
            out[f"{name}/cook_torrance"], out[f"{name}/principled"] = ct, pr
        return out
    except (KeyError, TypeError, ValueError, AttributeError) as exc:
        raise UserError(
            f"the plan's settings cannot be read by this ctlab ({type(exc).__name__}: "
            f"{str(exc)[:80]}); plan the job again into an empty folder"
        ) from None


_HASHES: dict = {}


def _hdri_hash(path: Path) -> str:
    """The HDRI's content hash, through the path gate (a regular file, opened without
    blocking: one replaced by a pipe or a folder after planning is refused, never read)."""
    path = input_file(
        path,
        "HDRI",
        missing=f"HDRI not found: {path} (the plan names it; on another machine it "
        "must be at the same path, or plan the job there)",
    )
    st = path.stat()
    key = (str(path), st.st_size, st.st_mtime_ns)
    if key not in _HASHES:
        _HASHES[key] = file_hash(path)
    return _HASHES[key]


def task_content(settings: MatrixSettings, samples: int, env: dict) -> dict:
    """What a render task's id is derived from: its settings with the HDRI's path replaced
    by its content hash (a farm may see it elsewhere), the samples and the versions."""
    data = settings_to_dict(settings)
    hdri = resolve_hdri(settings.hdri)
    data["hdri"] = ""
    data.pop("lights_file", None)
    inputs = {"hdri": _hdri_hash(hdri)}
    for key in ("albedo_texture", "normal_map"):  # textures by content too, where given
        if data.get(key):
            inputs[key] = _file_hash(data[key], key.replace("_", " "))
            data[key] = ""
    return {"settings": data, "samples": samples, "environment": env, "inputs": inputs}


def _file_hash(path, what: str) -> str:
    """An input's content hash, through the path gate (as _hdri_hash)."""
    path = input_file(path, what, missing=f"{what} not found: {path} (the plan names it)")
    st = path.stat()
    key = (str(path), st.st_size, st.st_mtime_ns)
    if key not in _HASHES:
        _HASHES[key] = sha256(path)
    return _HASHES[key]


def merge_outputs(job: str, spec: dict) -> tuple:
    if job == "matrix":
        return ("report.html",) + tuple(
            f"{c}/metrics.json" for c, *_ in pipeline.MATRIX_COMPARISONS
        )
    return ("report.html",)


def plan_merge_outputs(plan: dict) -> list:
    """The files the merge of a plan writes in the job folder (its report, the comparisons)."""
    names = list(merge_outputs(plan["job"], plan["spec"]))
    if plan["job"] == "matrix":
        names += [f"{c}/diff.png" for c, *_ in pipeline.MATRIX_COMPARISONS]
    return names


def plan_job(job: str, base: MatrixSettings, samples: int, **extra) -> dict:
    """The job's plan: its spec (base settings, samples, the parity HDRIs), a render task
    per folder, and the merge."""
    spec = {"base": settings_to_dict(base), "samples": samples}
    if job == "parity":
        spec.update(hdris=[str(h) for h in extra["hdris"]], name=extra.get("name"))
    env = environment()
    for path in {resolve_hdri(s.hdri) for s in renders_of(job, spec).values()}:
        load_hdri(path)  # every input checked before anything
    tasks = [
        jobgraph.render_task(folder, task_content(s, samples, env), renderer.OUTPUT_FILES)
        for folder, s in renders_of(job, spec).items()
    ]
    return jobgraph.make_plan(job, spec, env, tasks, merge_outputs(job, spec))


def write_job_folder(
    job_dir: Path, plan: dict, openjd: bool = False, replace: bool = False, flamenco: bool = False
) -> None:
    """JOB/plan.json (with ``openjd`` JOB/openjd/template.json, with ``flamenco``
    JOB/flamenco/ctlab-<job>.js). ``replace``: the job
    run in one process takes the folder over, as it always wrote over its renders."""
    # no input is an output of the job, and none of those is blocked or in the cache; the
    # bundles' places hold nothing of a user's: refused before anything is written
    for folder, settings in renders_of(plan["job"], plan["spec"]).items():
        pipeline.refuse_job_outputs(settings, job_dir, [folder])
    pipeline.refuse_job_outputs(
        settings_from_dict(plan["spec"]["base"]), job_dir, [], plan_merge_outputs(plan)
    )
    jobgraph.check_bundles(job_dir, plan["job"], openjd, flamenco)
    if replace:  # only a plan ctlab wrote (a user's plan.json is refused, never removed)
        jobgraph.owned_file(jobgraph.plan_path(job_dir), "the job's plan", _is_plan)
    check_writable(job_dir)
    if replace:
        jobgraph.plan_path(job_dir).unlink(missing_ok=True)
    jobgraph.write_plan(job_dir, plan)
    if openjd:
        jobgraph.write_openjd(Path(job_dir).resolve(), plan, PACKAGE_ROOT, sys.executable)
    if flamenco:
        jobgraph.write_flamenco(Path(job_dir).resolve(), plan, PACKAGE_ROOT, sys.executable)


def _is_plan(path: Path) -> bool:
    try:
        data = jobgraph.read_json(path, "plan", jobgraph.MAX_PLAN_BYTES)
    except UserError:
        return False
    return isinstance(data, dict) and data.get("format") == jobgraph.FORMAT


# ----------------------------------------------------------------------------------------
# One task


def _checked(job_dir: Path, plan: dict, task: dict) -> MatrixSettings:
    """The task's settings rebuilt by this version; its id must come out the same. Its
    paths are gated again (a plan is input): its folder inside the job folder through real
    folders, its outputs none of its inputs (jobgraph.check_task_paths,
    pipeline.refuse_job_outputs). An HDRI whose content changed since planning is named."""
    renders = renders_of(plan["job"], plan["spec"])
    s = renders.get(task["folder"])
    content = None if s is None else task_content(s, plan["spec"]["samples"], environment())
    if s is not None and content["inputs"] != task.get("inputs", content["inputs"]):
        changed = [k for k, v in content["inputs"].items() if task["inputs"].get(k) != v]
        name = {"hdri": f"HDRI {resolve_hdri(s.hdri)}"}.get(
            changed[0], f"{changed[0].replace('_', ' ')} {getattr(s, changed[0], '')}"
        )
        raise UserError(
            f"{name} changed since the job was planned (its content "
            "hash differs); put the planned file back, or plan the job again into an "
            "empty folder"
        )
    if s is None or jobgraph.content_id(task["folder"], content) != task["id"]:
        raise UserError(
            f"task {task['id']} was planned by another version or with other "
            f"settings (ctlab {plan.get('environment', {}).get('ctlab')}, Blender "
            f"{plan.get('environment', {}).get('blender')}); plan the job again "
            "into an empty folder"
        )
    jobgraph.check_task_paths(job_dir, task)
    pipeline.refuse_job_outputs(s, job_dir, [task["folder"]])
    return s


def process_age() -> float | None:
    """Seconds since this process started (Linux /proc), or None: a task's start-up cost
    (Python, bpy) is its age when the task begins."""
    try:
        start = int(Path("/proc/self/stat").read_text().rsplit(")", 1)[1].split()[19])
        uptime = float(Path("/proc/uptime").read_text().split()[0])
        return round(uptime - start / os.sysconf("SC_CLK_TCK"), 3)
    except (OSError, ValueError, IndexError):
        return None


def run_task(job_dir: Path, task_id: str, events=None, verbose: bool = False) -> dict:
    """``ctlab task JOB ID``: render one task into its folder and mark it done; a task done
    already does nothing. Returns {"ran": bool, "seconds": float}."""
    events = events or pipeline.Events()
    job_dir = Path(job_dir)
    plan = jobgraph.read_plan(job_dir)
    task = jobgraph.find_task(plan, task_id)
    if task["kind"] == "merge":
        merge(job_dir, events, verbose)
        return {"ran": True, "seconds": 0.0}
    s = _checked(job_dir, plan, task)
    if jobgraph.done(job_dir, task):
        events.note(f"task {task_id} is done already ({task['folder']})")
        return {"ran": False, "seconds": 0.0}
    started = process_age()
    start = time.perf_counter()
    scene = pipeline.render_one(
        s, job_dir / task["folder"], plan["spec"]["samples"], verbose=verbose, events=events
    )
    # the task's time split for the benchmark: process start-up, scene build and saving,
    # Cycles' synchronisation (the shader compile), Cycles' render
    jobgraph.mark_done(
        job_dir,
        task,
        {
            "process_start_seconds": started,
            "pid": os.getpid(),
            "task_seconds": round(time.perf_counter() - start, 3),
            **{
                k: scene.get(k) for k in ("render_seconds", "sync_seconds", "cycles_render_seconds")
            },
        },
    )
    return {"ran": True, "seconds": time.perf_counter() - start, "scene": scene}


# ----------------------------------------------------------------------------------------
# The merge


def _merge_folders(plan: dict, base: MatrixSettings) -> list:
    """The folders a merge writes in, relative to the job folder: the comparisons, the BRDF
    plots (matrix), each parity run's comparison."""
    if plan["job"] == "matrix":
        return [c for c, *_ in pipeline.MATRIX_COMPARISONS] + [
            f"plots/{name}" for name, *_ in plot_job.report_plots(base)
        ]
    runs = dict.fromkeys(t["folder"].split("/")[0] for t in jobgraph.render_tasks(plan))
    return [f"{name}/compare" for name in runs]


def merge(job_dir: Path, events=None, verbose: bool = False, steps: int | None = None) -> dict:
    """``ctlab merge JOB``: every render task checked (one line naming those to re-run),
    then the comparisons, plots and report from the job folder alone, under the merge lock."""
    events = events or pipeline.Events()
    job_dir = Path(job_dir)
    plan = jobgraph.read_plan(job_dir)
    planned = renders_of(plan["job"], plan["spec"])  # settings this version reads
    if [t["folder"] for t in jobgraph.render_tasks(plan)] != list(planned):
        raise UserError(
            f"{jobgraph.plan_path(job_dir)}: its render tasks are not the {plan['job']} "
            "job's; plan the job again into an empty folder"
        )
    jobgraph.check_complete(job_dir, plan)  # a refusal writes nothing: before the lock
    base = settings_from_dict(plan["spec"]["base"])
    pipeline.refuse_job_outputs(base, job_dir, [], plan_merge_outputs(plan))
    jobgraph.check_folders(job_dir, _merge_folders(plan, base), "the merge's outputs")
    check_writable(job_dir)
    with jobgraph.merge_lock(job_dir):
        jobgraph.check_complete(job_dir, plan)
        if plan["job"] == "matrix":
            return graph_merge.merge_matrix(job_dir, plan, base, events, verbose, steps)
        return graph_merge.merge_parity(job_dir, plan, events, steps)


# ----------------------------------------------------------------------------------------
# The jobs, run here


def run_matrix(
    base: MatrixSettings,
    samples: int,
    out: Path,
    events: pipeline.Events | None = None,
    verbose: bool = False,
    workers: int = 1,
) -> dict:
    """The main job: the OSL shader against Principled BSDF, the baked IBL modes against the
    reference integration, the node group against the OSL shader, the attribution and the
    white furnace, compared cell by cell, with report.html. Returns the comparisons. Its
    task graph run here (``workers``: render tasks as local processes); a render done
    already for the same settings and versions is kept."""
    events = events or pipeline.Events()
    plan = plan_job("matrix", base, samples)
    check_writable(out)
    pipeline._forget_report(out)
    write_job_folder(out, plan, replace=True)
    return run_graph(plan, out, events, verbose, workers)


def run_parity(
    base: MatrixSettings,
    hdris: list,
    samples: int,
    out: Path,
    events: pipeline.Events | None = None,
    verbose: bool = False,
    name: str | None = None,
    workers: int = 1,
) -> dict:
    """With Smith G, Lambert diffuse, metallic 1, the Sun off and no sphere shadowing another,
    the model is Principled BSDF's single-scatter GGX metal, so our reference integration and
    Cycles' path tracer must agree up to noise: both rendered under each HDRI (and the base's
    lights, if it has any) and compared, each into OUT/<HDRI stem>/, or OUT/<name>/ for a
    single HDRI given a name (the lights file's stem). Returns the verdict, the report and
    each run's comparison. Its task graph, run here."""
    events = events or pipeline.Events()
    plan = plan_job("parity", base, samples, hdris=hdris, name=name)
    check_writable(out)
    pipeline._forget_report(out)
    write_job_folder(out, plan, replace=True)
    return run_graph(plan, out, events, verbose, workers)


# ----------------------------------------------------------------------------------------
# The whole graph: in this process, or render tasks as local worker processes


def run_graph(
    plan: dict, job_dir: Path, events=None, verbose: bool = False, workers: int = 1
) -> dict:
    """Every render task not done yet (in this process, or ``workers`` processes running
    ``ctlab task``), then the merge. Progress: one step per render task, the merge's last."""
    events = events or pipeline.Events()
    job_dir = Path(job_dir)
    renders = jobgraph.render_tasks(plan)
    steps = len(renders) + (2 if plan["job"] == "matrix" else 1)
    if workers <= 1:
        for i, task in enumerate(renders):
            events.check()
            events.progress(i + 1, steps, describe_task(plan, task))
            result = run_task(job_dir, task["id"], events, verbose)
            if result["ran"]:
                events.note(f"{result['scene']['render_seconds']:.1f} s")
    else:
        run_workers(plan, job_dir, renders, workers, steps, events)
    return merge(job_dir, events, verbose, steps=steps)
