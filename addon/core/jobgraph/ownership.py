"""The job folder's own files: ctlab replaces or removes only what it wrote. Before a task,
a merge or a plan writes, each place it writes is absent or holds what ctlab wrote there (a
real folder, a regular file it recognises), reached through real folders only; a user's file,
a link, a folder or a pipe is refused in one line and left alone."""

from __future__ import annotations

import os
from pathlib import Path

from ..errors import UserError
from ..gate import describe, lstat, os_errors, owned_file, owned_folder  # noqa: F401
from ..paths import read_bytes
from .plan import TASKS_DIR, log_path, marker_path
from .schema import is_marker, safe_folder

LOG_MARK = "# ctlab task log"


def check_folders(job_dir: Path, folders, what: str) -> None:
    """Each folder (relative to the job folder) and each one on the way to it is absent or a
    real folder (owned_folder): nothing written below it can land outside the job folder."""
    for rel in folders:
        where = Path(job_dir)
        for name in rel.split("/"):
            where = where / name
            owned_folder(where, what)


def check_task_paths(job_dir: Path, task: dict) -> None:
    """Before a render task writes: its folder lies inside the job folder through real
    folders only (no link leads elsewhere), its outputs' places hold regular files or
    nothing, and the task records' folder and its marker are ctlab's (owned_folder,
    owned_file)."""
    job_dir = Path(job_dir)
    if not safe_folder(task.get("folder")):
        raise UserError(f"task {task.get('id')}'s folder leaves the job folder; plan again")
    check_folders(job_dir, [task["folder"]], f"task {task['id']}'s outputs")
    for rel in task["outputs"]:
        owned_file(job_dir / rel, f"task {task['id']}'s output")
    owned_folder(job_dir / TASKS_DIR, "its task records")
    owned_file(marker_path(job_dir, task), "a task's completion marker", is_marker)


def check_logs(job_dir: Path, tasks) -> None:
    """Before any worker starts: every task's log place is free or holds ctlab's log."""
    owned_folder(Path(job_dir) / TASKS_DIR, "its task records")
    for task in tasks:
        owned_file(log_path(job_dir, task), "a task's log", _is_log)


def open_log(job_dir: Path, task: dict):
    """A worker's log file, opened for writing without following a link or blocking; an
    earlier log is replaced only when ctlab wrote it (its first line is LOG_MARK)."""
    path = log_path(job_dir, task)
    owned_file(path, "a task's log", _is_log)
    with os_errors(path):
        fd = os.open(
            path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC | os.O_NOFOLLOW | os.O_NONBLOCK, 0o644
        )
    log = os.fdopen(fd, "w")
    log.write(f"{LOG_MARK}: {task['id']} ({task['folder']})\n")
    log.flush()
    return log


def starts_with(mark: str):
    """Whether a file ctlab wrote begins with ``mark`` (read without blocking)."""

    def test(path: Path) -> bool:
        try:
            return read_bytes(path, "file").startswith(mark.encode())
        except UserError:
            return False

    return test


_is_log = starts_with(LOG_MARK)
