"""A batch job as a task graph, as data: independent render tasks and a merge task that
depends on them, written to ``JOB/plan.json`` (versioned, each task with its command line),
run one task at a time by any number of processes or farm workers, and merged into the same
outputs, in the same layout, as the job run in one process.

- A task's id is derived from its content (core.jobgraph.content_id): its settings, the
  sample count, the model's and ctlab's versions, Blender's version and its inputs' content
  hashes (an HDRI's file hash, never its path), so a plan made elsewhere or later for other
  settings cannot pass for this one.
- A render task writes its folder whole (core.files.atomic_paths, through the renderer) and
  then its completion marker ``JOB/.tasks/<folder>.json`` (atomic, core.files.write_json)
  holding its id and its outputs' sizes and content hashes: a task whose marker matches is
  done and a re-run does nothing; a task killed before its marker is retried alone.
- The merge checks every render task first and names, in one line, the tasks to re-run; it
  holds an exclusive lock file (``JOB/.tasks/merge.lock``, O_CREAT|O_EXCL) so that two merges
  of one job never write at once.
- ``openjd_template`` writes the plan as an Open Job Description job template
  (specificationVersion jobtemplate-2023-09: https://github.com/OpenJobDescription/
  openjd-specifications/wiki/2023-09-Template-Schemas): job parameters defaulting to the
  planned job (PATH ones relative to the template's folder, as the spec requires), a Render
  step whose STRING task parameter is the task id, and a Report step depending on it.

Pure Python: no bpy (the jobs layer, jobs/graph.py, fills in what a task renders).
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import re
import socket
from pathlib import Path

from .errors import UserError
from .files import process_alive, sha256, write_json

FORMAT = "ctlab-plan"
PLAN_VERSION = 1
PLAN_FILE = "plan.json"
TASKS_DIR = ".tasks"
LOCK_FILE = "merge.lock"
OPENJD_DIR = "openjd"
OPENJD_SPEC = "jobtemplate-2023-09"


# ----------------------------------------------------------------------------------------
# Ids and hashes


def canonical(data) -> str:
    return json.dumps(data, sort_keys=True, separators=(",", ":"), allow_nan=False)


def content_id(prefix: str, content: dict) -> str:
    """``<prefix>-<12 hex digits of the SHA-256 of the content's canonical JSON>``; the
    prefix (a folder name) only makes ids readable."""
    slug = re.sub(r"[^A-Za-z0-9_]+", "_", prefix).strip("_") or "task"
    return f"{slug}-{hashlib.sha256(canonical(content).encode()).hexdigest()[:12]}"


def render_task(folder: str, content: dict, outputs: tuple) -> dict:
    """A render task writing ``outputs`` (file names) into JOB/<folder>/."""
    tid = content_id(folder, content)
    return {
        "id": tid,
        "kind": "render",
        "folder": folder,
        "command": ["ctlab", "task", "{job}", tid],
        "inputs": content.get("inputs", {}),
        "outputs": [f"{folder}/{name}" for name in outputs],
        "depends": [],
        "content": content,
    }


def merge_task(job: str, renders: list, outputs: tuple) -> dict:
    ids = [t["id"] for t in renders]
    return {
        "id": content_id(f"merge_{job}", {"depends": ids}),
        "kind": "merge",
        "command": ["ctlab", "merge", "{job}"],
        "inputs": {},
        "outputs": list(outputs),
        "depends": ids,
    }


def make_plan(job: str, spec: dict, environment: dict, renders: list, merge_outputs: tuple) -> dict:
    """``spec``: what the jobs layer needs to rebuild the tasks (the base settings, samples,
    the job's own choices); ``environment``: the versions every task id includes."""
    return {
        "format": FORMAT,
        "version": PLAN_VERSION,
        "job": job,
        "spec": spec,
        "environment": environment,
        "tasks": renders + [merge_task(job, renders, merge_outputs)],
    }


def render_tasks(plan: dict) -> list:
    return [t for t in plan["tasks"] if t["kind"] == "render"]


def find_task(plan: dict, task_id: str) -> dict:
    for t in plan["tasks"]:
        if t["id"] == task_id:
            return t
    raise UserError(
        f"no task {task_id!r} in this plan; its tasks: " + ", ".join(t["id"] for t in plan["tasks"])
    )


def order(plan: dict) -> list:
    """The tasks in an order where each follows those it depends on."""
    done, out, pending = set(), [], list(plan["tasks"])
    while pending:
        ready = [t for t in pending if set(t["depends"]) <= done]
        if not ready:
            raise UserError("the plan's tasks depend on each other in a cycle; plan again")
        for t in ready:
            out.append(t)
            done.add(t["id"])
            pending.remove(t)
    return out


# ----------------------------------------------------------------------------------------
# The plan file


def plan_path(job_dir: Path) -> Path:
    return Path(job_dir) / PLAN_FILE


def read_plan(job_dir: Path) -> dict:
    """JOB/plan.json, checked: a missing, unreadable or foreign file is one clear line."""
    path = plan_path(job_dir)
    try:
        plan = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise UserError(
            f"{job_dir} holds no {PLAN_FILE}; write one with 'ctlab plan matrix --out {job_dir}'"
        ) from None
    except (OSError, ValueError, UnicodeDecodeError) as exc:
        raise UserError(
            f"{path} is not a readable plan ({exc}); plan the job again into an empty folder"
        ) from None
    if not isinstance(plan, dict) or plan.get("format") != FORMAT:
        raise UserError(f"{path} is not a ctlab plan")
    if plan.get("version") != PLAN_VERSION:
        raise UserError(
            f"{path} is plan version {plan.get('version')}; this ctlab reads "
            f"version {PLAN_VERSION}: plan the job again"
        )
    if not isinstance(plan.get("tasks"), list) or not all(
        isinstance(t, dict) and {"id", "kind", "depends"} <= set(t) for t in plan["tasks"]
    ):
        raise UserError(f"{path} has malformed tasks; plan the job again")
    return plan


def write_plan(job_dir: Path, plan: dict) -> Path:
    """Write the plan, or keep the same plan already there; another plan in the folder is
    never overwritten (its tasks' outputs belong to it)."""
    path = plan_path(job_dir)
    if path.exists():
        try:
            old = read_plan(job_dir)
        except UserError:
            old = None
        if old is None or [t["id"] for t in old["tasks"]] != [t["id"] for t in plan["tasks"]]:
            raise UserError(
                f"{job_dir} already holds a plan of other settings or another "
                "version; choose another --out (nothing was overwritten)"
            )
        return path
    write_json(path, plan)
    return path


# ----------------------------------------------------------------------------------------
# Completion markers


def marker_path(job_dir: Path, task: dict) -> Path:
    return Path(job_dir) / TASKS_DIR / (task["folder"].replace("/", "__") + ".json")


def output_manifest(job_dir: Path, task: dict) -> dict:
    return {
        rel: {
            "bytes": (Path(job_dir) / rel).stat().st_size,
            "sha256": sha256(Path(job_dir) / rel),
        }
        for rel in task["outputs"]
    }


def mark_done(job_dir: Path, task: dict, info: dict | None = None) -> None:
    """After the task's outputs are whole: its marker, written atomically."""
    (Path(job_dir) / TASKS_DIR).mkdir(exist_ok=True)
    write_json(
        marker_path(job_dir, task),
        {
            "id": task["id"],
            "version": PLAN_VERSION,
            "outputs": output_manifest(job_dir, task),
            "info": info or {},
        },
    )


def problem(job_dir: Path, task: dict) -> str | None:
    """Why a render task is not done, in a few words, or None when it is."""
    try:
        marker = json.loads(marker_path(job_dir, task).read_text(encoding="utf-8"))
    except FileNotFoundError:
        return "has not run"
    except (OSError, ValueError, UnicodeDecodeError):
        return "has a corrupt completion marker"
    if not isinstance(marker, dict) or marker.get("id") != task["id"]:
        return (
            f"holds the output of another version or other settings "
            f"({marker.get('id') if isinstance(marker, dict) else '?'})"
        )
    recorded = marker.get("outputs") or {}
    for rel in task["outputs"]:
        path = Path(job_dir) / rel
        if not path.is_file():
            return f"lost its output {rel}"
        want = recorded.get(rel) or {}
        if path.stat().st_size != want.get("bytes") or sha256(path) != want.get("sha256"):
            return f"has a corrupt output {rel} (changed since the task finished)"
    return None


def done(job_dir: Path, task: dict) -> bool:
    return problem(job_dir, task) is None


def check_complete(job_dir: Path, plan: dict, python_cmd: str = "ctlab") -> None:
    """Every render task done, or one UserError line naming each task to re-run and why."""
    bad = [(t, why) for t in render_tasks(plan) if (why := problem(job_dir, t))]
    if bad:
        raise UserError(
            f"{job_dir} is not ready to merge: "
            + "; ".join(f"task {t['id']} ({t['folder']}) {why}" for t, why in bad)
            + ". Re-run: "
            + "; ".join(f"{python_cmd} task {job_dir} {t['id']}" for t, _ in bad)
        )


# ----------------------------------------------------------------------------------------
# One merge at a time


@contextlib.contextmanager
def merge_lock(job_dir: Path):
    """An exclusive lock file for the merge of one job. A lock left by a process of this
    host that no longer runs is taken over; a live one (or another host's) is a UserError."""
    folder = Path(job_dir) / TASKS_DIR
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / LOCK_FILE
    me = f"{socket.gethostname()} {os.getpid()}"
    for _ in range(2):
        try:
            fd = os.open(path, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
            break
        except FileExistsError:
            try:
                host, pid = path.read_text().split()
                pid = int(pid)
            except (OSError, ValueError):
                host, pid = "?", -1
            if host == socket.gethostname() and pid > 0 and not process_alive(pid):
                with contextlib.suppress(OSError):
                    path.unlink()
                continue
            raise UserError(
                f"another merge of {job_dir} is running (process {pid} on "
                f"{host}); wait for it, or remove {path} if it is gone"
            ) from None
    else:
        raise UserError(f"could not take the merge lock {path}; remove it and merge again")
    try:
        os.write(fd, me.encode())
        os.close(fd)
        yield
    finally:
        with contextlib.suppress(OSError):
            path.unlink()


# ----------------------------------------------------------------------------------------
# Open Job Description


def openjd_template(plan: dict) -> dict:
    """The plan as an Open Job Description job template (jobtemplate-2023-09) for
    JOB/openjd/template.json. The spec joins a PATH parameter's default to the template's
    folder and forbids walking up from it, so the defaults name what lies in JOB/openjd/:
    BundleDir "." (the job folder is its parent), RepoRoot "ctlab" (a link to Cook-Torrance
    Lab's folder, write_openjd); a farm remaps or overrides both. Python (a Python with bpy)
    is a STRING defaulting to this machine's. A Render step over the render task ids (a
    STRING task parameter), a Report step that depends on it."""
    ids = [t["id"] for t in render_tasks(plan)]
    job = "{{Param.BundleDir}}/.."

    def action(*args):
        return {
            "actions": {
                "onRun": {
                    "command": "{{Param.Python}}",
                    "args": ["{{Param.RepoRoot}}/scripts/ctlab.py", *args],
                }
            }
        }

    return {
        "specificationVersion": OPENJD_SPEC,
        "name": f"ctlab {plan['job']}",
        "parameterDefinitions": [
            {
                "name": "BundleDir",
                "type": "PATH",
                "objectType": "DIRECTORY",
                "default": ".",
                "description": "this bundle, JOB/openjd: the job folder (plan.json) is its parent",
            },
            {
                "name": "RepoRoot",
                "type": "PATH",
                "objectType": "DIRECTORY",
                "default": "ctlab",
                "description": "Cook-Torrance Lab's folder (scripts/ctlab.py)",
            },
            {
                "name": "Python",
                "type": "STRING",
                "minLength": 1,
                "default": plan.get("python", "python3"),
                "description": "a Python with bpy (Blender as a module)",
            },
        ],
        "steps": [
            {
                "name": "Render",
                "parameterSpace": {
                    "taskParameterDefinitions": [{"name": "TaskId", "type": "STRING", "range": ids}]
                },
                "script": action("task", job, "{{Task.Param.TaskId}}"),
            },
            {
                "name": "Report",
                "dependencies": [{"dependsOn": "Render"}],
                "script": action("merge", job),
            },
        ],
    }


def write_openjd(job_dir: Path, plan: dict, repo_root: Path, python: str) -> Path:
    """JOB/openjd/template.json, a job bundle folder (``deadline bundle submit JOB/openjd``),
    and JOB/openjd/ctlab, a link to ``repo_root`` (RepoRoot's default)."""
    folder = Path(job_dir) / OPENJD_DIR
    folder.mkdir(exist_ok=True)
    link = folder / "ctlab"
    if link.is_symlink() or link.exists():
        link.unlink()
    link.symlink_to(Path(repo_root).absolute(), target_is_directory=True)
    path = folder / "template.json"
    write_json(path, openjd_template(dict(plan, python=str(python))))
    return path


# ----------------------------------------------------------------------------------------
# Flamenco

FLAMENCO_DIR = "flamenco"


def flamenco_job_type(plan: dict, job_dir: Path, repo_root: Path, python: str) -> str:
    """A Flamenco 3 job compiler script (JavaScript; https://flamenco.blender.org/usage/
    job-types/) for this plan: its settings are the job folder, Cook-Torrance Lab's folder
    and the Python (defaults: this machine's), and compileJob authors one ``exec`` task per
    render task (``ctlab task JOB ID``) and a merge task that depends on all of them. The
    task ids are the plan's: Flamenco scripts cannot read plan.json themselves."""
    ids = [t["id"] for t in render_tasks(plan)]
    digest = hashlib.sha256(canonical(ids).encode()).hexdigest()[:8]
    setting = (
        '    {{ key: "{key}", type: "string", {sub}required: true, '
        'default: {default}, description: {desc} }},'
    )
    settings = "\n".join(
        setting.format(key=k, sub=sub, default=json.dumps(str(v)), desc=json.dumps(d))
        for k, sub, v, d in (
            ("job_dir", 'subtype: "dir_path", ', job_dir, "the job folder (plan.json)"),
            (
                "repo_root",
                'subtype: "dir_path", ',
                repo_root,
                "Cook-Torrance Lab's folder (scripts/ctlab.py)",
            ),
            ("python", 'subtype: "file_path", ', python, "a Python with bpy (Blender as a module)"),
        )
    )
    return f"""// Flamenco job type for one planned Cook-Torrance Lab job, written by
// `ctlab plan {plan['job']} --flamenco` (addon/core/jobgraph.py). Put it in the Manager's
// scripts/ folder; the task ids below are the plan's.
const JOB_TYPE = {{
  label: {json.dumps(f"ctlab {plan['job']} {digest}")},
  description: "Cook-Torrance Lab: render tasks, then the merge (report)",
  settings: [
{settings}
  ],
}};

const TASK_IDS = {json.dumps(ids)};

function compileJob(job) {{
  const s = job.settings;
  const ctlab = s.repo_root + "/scripts/ctlab.py";
  const renders = [];
  for (const id of TASK_IDS) {{
    const task = author.Task("render-" + id, "misc");
    task.addCommand(author.Command("exec", {{ exe: s.python,
                                              args: [ctlab, "task", s.job_dir, id] }}));
    job.addTask(task);
    renders.push(task);
  }}
  const merge = author.Task("merge", "misc");
  merge.addCommand(author.Command("exec", {{ exe: s.python,
                                             args: [ctlab, "merge", s.job_dir] }}));
  for (const task of renders) {{
    merge.addDependency(task);
  }}
  job.addTask(merge);
}}
"""


def write_flamenco(job_dir: Path, plan: dict, repo_root: Path, python: str) -> Path:
    """JOB/flamenco/ctlab-<job>.js (flamenco_job_type)."""
    folder = Path(job_dir) / FLAMENCO_DIR
    folder.mkdir(exist_ok=True)
    path = folder / f"ctlab-{plan['job']}.js"
    from .files import write_text

    write_text(path, flamenco_job_type(plan, Path(job_dir).absolute(), repo_root, python))
    return path
