"""A job's render tasks as local worker processes (``ctlab matrix --workers N``): each task
a ``ctlab task`` process (scripts/ctlab.py), at most N at a time, logging into the job
folder (core/jobgraph/markers.py); jobs/graph.py runs the graph and the merge."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

from . import graph_merge, pipeline
from ..core import jobgraph
from ..core.errors import Cancelled, UserError
from ..core.files import PACKAGE_ROOT
from ..core.settings import settings_from_dict

CTLAB_SCRIPT = PACKAGE_ROOT / "scripts" / "ctlab.py"


def describe_task(plan: dict, task: dict) -> str:
    """A render task in words, for the progress lines: its render, grid, size and samples."""
    s = settings_from_dict(plan["spec"]["base"])
    samples = plan["spec"]["samples"]
    folder = task["folder"]
    if plan["job"] == "matrix":
        r = pipeline.matrix_settings(s)[folder]
        return (
            f"{graph_merge.matrix_labels()[folder]}: grid {r.rows}x{r.cols}, "
            f"{r.width}x{r.height} px, {samples} samples"
        )
    name, what = folder.split("/")
    return f"{name}: {what}, grid {s.rows}x{s.cols}, {s.width} px, {samples} samples"


def task_command(job_dir: Path, task_id: str) -> list:
    return [sys.executable, str(CTLAB_SCRIPT), "task", str(job_dir), task_id]


def run_workers(plan, job_dir, renders, workers, steps, events) -> None:
    """The render tasks not done yet as ``workers`` local ``ctlab task`` processes at a time,
    each logging into the job folder's task logs; progress as each ends. A failed task stops
    the others from starting and is one line naming it, its exit status, its log's last line
    and the command that re-runs it; a cancel terminates the running ones."""
    pending = [t for t in renders if not jobgraph.done(job_dir, t)]
    running, failed, finished = {}, [], len(renders) - len(pending)
    logs = job_dir / jobgraph.TASKS_DIR
    jobgraph.check_logs(job_dir, pending)
    with jobgraph.os_errors(logs):
        logs.mkdir(exist_ok=True)
    env = {k: v for k, v in os.environ.items() if k != "CTLAB_JSON_EVENTS"}
    try:
        while pending or running:
            if events.cancelled():
                raise Cancelled()
            while pending and len(running) < workers and not failed:
                task = pending.pop(0)
                log = jobgraph.open_log(job_dir, task)
                proc = subprocess.Popen(
                    task_command(job_dir, task["id"]), stdout=log, stderr=subprocess.STDOUT, env=env
                )
                running[proc] = (task, log, time.perf_counter())
            if failed and not running:
                break
            time.sleep(0.1)
            for proc in [p for p in running if p.poll() is not None]:
                task, log, start = running.pop(proc)
                log.close()
                if proc.returncode:
                    failed.append((task, proc.returncode))
                    continue
                finished += 1
                events.progress(
                    finished,
                    steps,
                    f"{describe_task(plan, task)} "
                    f"({time.perf_counter() - start:.1f} s, worker process)",
                )
    finally:
        for proc, (_, log, _) in running.items():
            proc.terminate()
            proc.wait()
            log.close()
    if failed:
        task, code = failed[0]
        tail = ""
        log = jobgraph.log_path(job_dir, task)
        try:
            text = log.read_text(errors="replace")
        except OSError:
            text = ""
        lines = [ln for ln in text.splitlines() if ln.strip()]
        tail = f": {lines[-1]}" if lines else ""
        raise UserError(
            f"task {task['id']} ({task['folder']}) failed (exit {code}){tail}; "
            f"re-run: ctlab task {job_dir} {task['id']} (log: {log})"
        )
