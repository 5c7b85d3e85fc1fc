"""Completion markers and the merge lock. A render task, after its folder is whole, writes
its marker ``JOB/.tasks/<folder>.json`` (atomic) holding its id and its outputs' sizes and
content hashes: a task whose marker matches is done. The merge checks every render task first
and holds ``JOB/.tasks/merge.lock`` (O_CREAT|O_EXCL), so that two merges of one job never
write at once."""

from __future__ import annotations

import contextlib
import os
import socket
import stat
from pathlib import Path

from ..errors import UserError
from ..files import process_alive, sha256, write_json
from ..paths import read_bytes
from .ownership import describe, lstat, os_errors, owned_file, owned_folder
from .plan import PLAN_VERSION, TASKS_DIR, marker_path, render_tasks
from .schema import MAX_MARKER_BYTES, is_marker, marker_problem, read_json

LOCK_FILE = "merge.lock"


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
    folder = Path(job_dir) / TASKS_DIR
    owned_folder(folder, "its task records")
    with os_errors(folder):
        folder.mkdir(exist_ok=True)
    owned_file(marker_path(job_dir, task), "a task's completion marker", is_marker)
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
    """Why a render task is not done, in a few words, or None when it is. The marker is
    read without blocking (read_json); each output must be a regular file (not a link)
    holding the bytes the marker records."""
    path = marker_path(job_dir, task)
    if not os.path.lexists(path):
        return "has not run"
    try:
        marker = read_json(path, "completion marker", MAX_MARKER_BYTES)
    except UserError:
        return "has a corrupt completion marker"
    why = marker_problem(marker, task)
    if why:
        return why
    for rel in task["outputs"]:
        out = Path(job_dir) / rel
        try:
            st = os.lstat(out)
        except OSError:
            return f"lost its output {rel}"
        if not stat.S_ISREG(st.st_mode):
            return f"lost its output {rel} ({describe(st.st_mode)} stands there)"
        want = marker["outputs"][rel]
        try:
            same = st.st_size == want["bytes"] and sha256(out) == want["sha256"]
        except OSError:
            same = False
        if not same:
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


def _lock_holder(path: Path):
    """(host, pid) of a lock file ctlab wrote, or None for anything else."""
    try:
        host, pid = read_bytes(path, "merge lock").decode().split()
        return host, int(pid)
    except (UserError, ValueError, UnicodeDecodeError):
        return None


@contextlib.contextmanager
def merge_lock(job_dir: Path):
    """An exclusive lock file for the merge of one job. A lock left by a process of this
    host that no longer runs is taken over; a live one (or another host's) is a UserError;
    anything at the lock's place that ctlab did not write (a link, a pipe, a user's file) is
    refused and left alone."""
    folder = Path(job_dir) / TASKS_DIR
    owned_folder(folder, "its task records")
    with os_errors(folder):
        folder.mkdir(parents=True, exist_ok=True)
    path = folder / LOCK_FILE
    me = f"{socket.gethostname()} {os.getpid()}"
    for _ in range(2):
        try:
            fd = os.open(path, os.O_CREAT | os.O_EXCL | os.O_WRONLY | os.O_NOFOLLOW, 0o644)
            break
        except FileExistsError:
            st = lstat(path)
            holder = _lock_holder(path) if st and stat.S_ISREG(st.st_mode) else None
            if holder is None:
                raise UserError(
                    f"{path} is not a merge lock ctlab wrote; move it away and merge "
                    "again (it was left alone)"
                ) from None
            host, pid = holder
            if host == socket.gethostname() and pid > 0 and not process_alive(pid):
                with contextlib.suppress(OSError):
                    path.unlink()
                continue
            raise UserError(
                f"another merge of {job_dir} is running (process {pid} on "
                f"{host}); wait for it, or remove {path} if it is gone"
            ) from None
        except OSError as exc:
            with os_errors(path):
                raise exc
    else:
        raise UserError(f"could not take the merge lock {path}; remove it and merge again")
    try:
        with os_errors(path):
            os.write(fd, me.encode())
            os.close(fd)
        yield
    finally:
        if _lock_holder(path) == (socket.gethostname(), os.getpid()):
            with contextlib.suppress(OSError):
                path.unlink()
