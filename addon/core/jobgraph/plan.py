"""A job's task graph as data: the plan (``JOB/plan.json``'s content), its tasks and their
content ids, and where each of the job folder's records lies (the plan, the completion
markers, the workers' logs)."""

from __future__ import annotations

import hashlib
import json
import re
from pathlib import Path

from ..errors import UserError

FORMAT = "ctlab-plan"
PLAN_VERSION = 1
PLAN_FILE = "plan.json"
TASKS_DIR = ".tasks"


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
# Where the job folder's records lie


def plan_path(job_dir: Path) -> Path:
    return Path(job_dir) / PLAN_FILE


def marker_name(folder: str) -> str:
    return folder.replace("/", "__") + ".json"


def marker_path(job_dir: Path, task: dict) -> Path:
    return Path(job_dir) / TASKS_DIR / marker_name(task["folder"])


def log_path(job_dir: Path, task: dict) -> Path:
    """A worker process's output (``ctlab matrix --workers``), beside the task's marker."""
    return marker_path(job_dir, task).with_suffix(".log")
