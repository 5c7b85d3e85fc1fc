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
import stat
from pathlib import Path

from .errors import UserError
from .files import WRITE_ERRORS, process_alive, sha256, staging_name, write_json, write_text
from .paths import kind, read_bytes, safe_name

FORMAT = "ctlab-plan"
PLAN_VERSION = 1
PLAN_FILE = "plan.json"
TASKS_DIR = ".tasks"
LOCK_FILE = "merge.lock"
OPENJD_DIR = "openjd"
OPENJD_SPEC = "jobtemplate-2023-09"
FLAMENCO_DIR = "flamenco"
FLAMENCO_MARK = "// Flamenco job type for one planned Cook-Torrance Lab job"
LOG_MARK = "# ctlab task log"

# A plan and a marker are input (a user, a farm or a broken tool may have edited them): their
# size and nesting are bounded before they are parsed or walked.
MAX_PLAN_BYTES = 64 << 20
MAX_MARKER_BYTES = 1 << 20
MAX_DEPTH = 64  # a plan ctlab writes nests 6 levels deep (8 with lights)
MAX_TASKS = 4096
_ID = re.compile(r"[A-Za-z0-9_]{1,80}-[0-9a-f]{12}", re.ASCII)
_HEX64 = re.compile(r"[0-9a-f]{64}", re.ASCII)


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


def read_json(path: Path, what: str, limit: int, missing: str | None = None):
    """An untrusted JSON file (a plan, a marker, a lock): a regular file read without
    blocking (core.paths.read_bytes: a named pipe, a folder or a device is refused), at most
    ``limit`` bytes, UTF-8, standard JSON, nested at most MAX_DEPTH deep; else one UserError
    line naming the file."""
    try:
        size = os.stat(path).st_size
    except OSError:
        size = 0
    if size > limit:
        raise UserError(f"{what} {path} is {size} bytes, over the {limit} this ctlab reads")
    raw = read_bytes(path, what, missing)
    if len(raw) > limit:
        raise UserError(f"{what} {path} is over the {limit} bytes this ctlab reads")
    try:
        data = json.loads(raw.decode("utf-8"))
    except RecursionError:
        raise UserError(f"{path} is not a readable {what} (nested too deep)") from None
    except (ValueError, UnicodeDecodeError) as exc:
        raise UserError(f"{path} is not a readable {what} ({exc})") from None
    if depth(data) > MAX_DEPTH:
        raise UserError(f"{path} is not a readable {what} (nested over {MAX_DEPTH} levels)")
    return data


def depth(data) -> int:
    """How deep lists and objects nest in parsed JSON (iterative: never a RecursionError)."""
    deepest, stack = 0, [(data, 1)]
    while stack:
        item, level = stack.pop()
        if isinstance(item, dict):
            item = list(item.values())
        if isinstance(item, list):
            deepest = max(deepest, level)
            if level <= MAX_DEPTH:
                stack.extend((v, level + 1) for v in item)
    return deepest


def safe_folder(rel, parts: tuple = (1, 2)) -> bool:
    """A relative path a plan may name inside its job folder: ``parts`` names, each one a
    safe name (core.paths.safe_name: ASCII letters, digits and ``._+-``, no leading dot,
    so never ``..``), joined by single slashes."""
    if not isinstance(rel, str):
        return False
    names = rel.split("/")
    return parts[0] <= len(names) <= parts[1] and all(
        n and safe_name(n, "") == n and n != TASKS_DIR for n in names
    )


def _int(v) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


def _str_list(v) -> bool:
    return isinstance(v, list) and all(isinstance(x, str) for x in v)


def plan_problems(plan) -> list:
    """What is wrong with a parsed plan, one short phrase per problem (empty: none). Every
    field ctlab reads is checked for its type, and every path in it for staying inside the
    job folder (safe_folder), so that no edit of plan.json makes ``task`` or ``merge`` write
    elsewhere or fail with a traceback."""
    if not isinstance(plan, dict):
        return ["it is not a JSON object"]
    if plan.get("format") != FORMAT:
        return ["it is not a ctlab plan (no format 'ctlab-plan')"]
    if plan.get("version") != PLAN_VERSION or not _int(plan.get("version")):
        return [
            f"it is plan version {str(plan.get('version'))[:20]}; this ctlab reads "
            f"version {PLAN_VERSION}"
        ]
    out = []
    if not (isinstance(plan.get("job"), str) and safe_folder(plan["job"], (1, 1))):
        out.append("'job' is not a job name")
    spec = plan.get("spec")
    if not isinstance(spec, dict):
        out.append("'spec' is not an object")
    else:
        if not isinstance(spec.get("base"), dict):
            out.append("'spec.base' is not an object of settings")
        if not (_int(spec.get("samples")) and 1 <= spec["samples"] <= 1 << 16):
            out.append("'spec.samples' is not a sample count")
        if "hdris" in spec and not (_str_list(spec["hdris"]) and spec["hdris"]):
            out.append("'spec.hdris' is not a list of HDRI paths")
        if spec.get("name") is not None and not isinstance(spec["name"], str):
            out.append("'spec.name' is not a name")
    if not isinstance(plan.get("environment"), dict):
        out.append("'environment' is not an object")
    tasks = plan.get("tasks")
    if not (isinstance(tasks, list) and 1 < len(tasks) <= MAX_TASKS):
        return out + ["'tasks' is not a list of tasks"]
    ids, markers, merges = set(), set(), 0
    for i, t in enumerate(tasks):
        where = f"task {i + 1}"
        if not isinstance(t, dict):
            out.append(f"{where} is not an object")
            continue
        if not (isinstance(t.get("id"), str) and _ID.fullmatch(t["id"])):
            out.append(f"{where} has no valid 'id'")
        elif t["id"] in ids:
            out.append(f"{where} repeats the id {t['id']}")
        else:
            ids.add(t["id"])
            where = f"task {t['id']}"
        if not _str_list(t.get("depends")):
            out.append(f"{where}: 'depends' is not a list of ids")
        if not _str_list(t.get("command")):
            out.append(f"{where}: 'command' is not a list of words")
        if not isinstance(t.get("inputs", {}), dict):
            out.append(f"{where}: 'inputs' is not an object")
        outputs = t.get("outputs")
        if t.get("kind") == "render":
            folder = t.get("folder")
            if not safe_folder(folder):
                out.append(f"{where}: 'folder' is not a folder inside the job folder")
                continue
            if marker_name(folder) in markers:
                out.append(f"{where}: its folder {folder} repeats another task's")
            markers.add(marker_name(folder))
            if not isinstance(t.get("content"), dict):
                out.append(f"{where}: 'content' is not an object")
            if not (
                _str_list(outputs)
                and outputs
                and all(o.startswith(folder + "/") and safe_folder(o, (2, 3)) for o in outputs)
            ):
                out.append(f"{where}: 'outputs' are not files inside its folder {folder}")
        elif t.get("kind") == "merge":
            merges += 1
            if not (_str_list(outputs) and all(safe_folder(o, (1, 3)) for o in outputs)):
                out.append(f"{where}: 'outputs' are not files inside the job folder")
        else:
            out.append(f"{where}: 'kind' is neither render nor merge")
    if merges != 1:
        out.append(f"it has {merges} merge tasks, not one")
    unknown = {
        d
        for t in tasks
        if isinstance(t, dict) and _str_list(t.get("depends"))
        for d in t["depends"]
    } - ids
    if unknown and not out:
        out.append(f"tasks depend on tasks it does not have ({', '.join(sorted(unknown))[:80]})")
    return out


def check_plan(plan, path) -> dict:
    """The plan, or one UserError line listing its first problems (plan_problems)."""
    problems = plan_problems(plan)
    if problems:
        more = f" (and {len(problems) - 3} more)" if len(problems) > 3 else ""
        raise UserError(
            f"{path} is not a plan this ctlab can run: {'; '.join(problems[:3])}{more}; "
            "plan the job again into an empty folder"
        )
    return plan


def read_plan(job_dir: Path) -> dict:
    """JOB/plan.json, checked (read_json, plan_problems): a missing, unreadable, damaged or
    foreign file is one clear line; a named pipe never blocks."""
    path = plan_path(job_dir)
    plan = read_json(
        path,
        "plan",
        MAX_PLAN_BYTES,
        missing=f"{job_dir} holds no {PLAN_FILE}; write one with "
        f"'ctlab plan matrix --out {job_dir}'",
    )
    return check_plan(plan, path)


def write_plan(job_dir: Path, plan: dict) -> Path:
    """Write the plan, or keep the same plan already there; another plan in the folder is
    never overwritten (its tasks' outputs belong to it)."""
    path = plan_path(job_dir)
    if os.path.lexists(path):
        try:
            old = read_plan(job_dir)
        except UserError as exc:
            raise UserError(
                f"{job_dir} already holds a {PLAN_FILE} this ctlab cannot use ({exc}); "
                "choose another --out (nothing was overwritten)"
            ) from None
        if [t["id"] for t in old["tasks"]] != [t["id"] for t in plan["tasks"]]:
            raise UserError(
                f"{job_dir} already holds a plan of other settings or another "
                "version; choose another --out (nothing was overwritten)"
            )
        return path
    write_json(path, plan)
    return path


# ----------------------------------------------------------------------------------------
# Completion markers


def marker_name(folder: str) -> str:
    return folder.replace("/", "__") + ".json"


def marker_path(job_dir: Path, task: dict) -> Path:
    return Path(job_dir) / TASKS_DIR / marker_name(task["folder"])


def log_path(job_dir: Path, task: dict) -> Path:
    """A worker process's output (``ctlab matrix --workers``), beside the task's marker."""
    return marker_path(job_dir, task).with_suffix(".log")


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


def marker_problem(marker, task: dict) -> str | None:
    """What is wrong with a parsed completion marker of ``task``, or None (every field ctlab
    reads, by type: a damaged marker is a task to re-run, never a traceback)."""
    if not isinstance(marker, dict) or not isinstance(marker.get("id"), str):
        return "has a corrupt completion marker"
    if marker["id"] != task["id"]:
        return f"holds the output of another version or other settings ({marker['id'][:40]})"
    outputs = marker.get("outputs")
    if not isinstance(outputs, dict) or not all(
        isinstance(outputs.get(rel), dict)
        and _int(outputs[rel].get("bytes"))
        and isinstance(outputs[rel].get("sha256"), str)
        and _HEX64.fullmatch(outputs[rel]["sha256"])
        for rel in task["outputs"]
    ):
        return "has a corrupt completion marker"
    return None


def is_marker(path: Path) -> bool:
    """Whether a file is a completion marker ctlab wrote (a JSON object with an id and
    outputs): only such a file is replaced by a task's new marker."""
    try:
        data = read_json(path, "marker", MAX_MARKER_BYTES)
    except UserError:
        return False
    return isinstance(data, dict) and {"id", "outputs"} <= set(data)


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
# The job folder's own files: ctlab replaces or removes only what it wrote


def describe(mode: int) -> str:
    """What a file of this (lstat) mode is, with its article: "a link", "a folder", ..."""
    return "a link" if stat.S_ISLNK(mode) else kind(mode) or "a file"


@contextlib.contextmanager
def os_errors(path):
    """Any OSError in the block as one UserError line naming the file (core.files'
    WRITE_ERRORS for the causes a user can remedy)."""
    try:
        yield
    except OSError as exc:
        name = exc.filename or path
        cause = WRITE_ERRORS.get(exc.errno) or exc.strerror or str(exc)
        raise UserError(f"cannot use {name}: {cause}; nothing was changed there") from None


def _lstat(path: Path):
    try:
        return os.lstat(path)
    except FileNotFoundError:
        return None
    except NotADirectoryError:
        raise UserError(f"{path} lies below a file; move it away or choose another --out") from None
    except OSError as exc:
        raise UserError(f"cannot use {path}: {exc.strerror or exc}") from None


def owned_folder(path: Path, what: str) -> None:
    """``path``, where ctlab keeps ``what``, is absent or a real folder (not a link to one:
    ctlab would write into a folder it did not choose); else one UserError line."""
    st = _lstat(Path(path))
    if st is not None and (stat.S_ISLNK(st.st_mode) or not stat.S_ISDIR(st.st_mode)):
        raise UserError(
            f"{path} is {describe(st.st_mode)} where ctlab keeps {what}; "
            "move it away (nothing was written)"
        )


def owned_file(path: Path, what: str, ours=None) -> None:
    """``path``, where ctlab writes ``what``, is absent, or a regular file (not a link) that
    ``ours(path)`` says ctlab wrote (None: any regular file, an output of the job itself);
    a user's file, a link, a folder or a pipe is refused in one line before anything is
    written, so it is never replaced or removed."""
    st = _lstat(Path(path))
    if st is None:
        return
    if not stat.S_ISREG(st.st_mode):
        raise UserError(
            f"{path} is {describe(st.st_mode)} where ctlab writes {what}; move it "
            "away (nothing was written)"
        )
    if ours is not None and not ours(Path(path)):
        raise UserError(
            f"{path} is a file ctlab did not write, where it writes {what}; move it "
            "away (nothing was written)"
        )


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


def _starts_with(mark: str):
    """Whether a file ctlab wrote begins with ``mark`` (read without blocking)."""

    def test(path: Path) -> bool:
        try:
            return read_bytes(path, "file").startswith(mark.encode())
        except UserError:
            return False

    return test


_is_log = _starts_with(LOG_MARK)


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
            st = _lstat(path)
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


def _is_template(path: Path) -> bool:
    try:
        data = read_json(path, "template", MAX_PLAN_BYTES)
    except UserError:
        return False
    return (
        isinstance(data, dict)
        and data.get("specificationVersion") == OPENJD_SPEC
        and str(data.get("name", "")).startswith("ctlab ")
    )


def _is_ctlab_link(path: Path) -> bool:
    """A link ctlab made to a Cook-Torrance Lab folder (one holding scripts/ctlab.py)."""
    try:
        return (Path(path).parent / os.readlink(path) / "scripts" / "ctlab.py").is_file()
    except OSError:
        return False


def check_bundles(job_dir: Path, job: str, openjd: bool, flamenco: bool) -> None:
    """Before ``ctlab plan`` writes anything: the bundles' folders are absent or real folders,
    and every file they replace is one ctlab wrote (a template, a job type, the RepoRoot
    link); a user's file there is refused in one line and left alone."""
    job_dir = Path(job_dir)
    owned_folder(job_dir / TASKS_DIR, "its task records")
    if openjd:
        folder = job_dir / OPENJD_DIR
        owned_folder(folder, "the Open Job Description bundle")
        link = folder / "ctlab"
        st = _lstat(link)
        if st is not None and not (stat.S_ISLNK(st.st_mode) and _is_ctlab_link(link)):
            raise UserError(
                f"{link} is {describe(st.st_mode)} ctlab did not make, where it links "
                "Cook-Torrance Lab's folder; move it away (nothing was written)"
            )
        owned_file(folder / "template.json", "the job template", _is_template)
    if flamenco:
        folder = job_dir / FLAMENCO_DIR
        owned_folder(folder, "the Flamenco job type")
        owned_file(folder / f"ctlab-{job}.js", "the Flamenco job type", _starts_with(FLAMENCO_MARK))


def write_openjd(job_dir: Path, plan: dict, repo_root: Path, python: str) -> Path:
    """JOB/openjd/template.json, a job bundle folder (``deadline bundle submit JOB/openjd``),
    and JOB/openjd/ctlab, a link to ``repo_root`` (RepoRoot's default), put in place by a
    rename (a link or file there that ctlab did not make is refused first, check_bundles)."""
    check_bundles(job_dir, plan["job"], openjd=True, flamenco=False)
    folder = Path(job_dir) / OPENJD_DIR
    link = folder / "ctlab"
    staged = staging_name(link)
    with os_errors(folder):
        folder.mkdir(exist_ok=True)
        try:
            staged.symlink_to(Path(repo_root).absolute(), target_is_directory=True)
            os.replace(staged, link)
        finally:
            with contextlib.suppress(OSError):
                staged.unlink()
    path = folder / "template.json"
    write_json(path, openjd_template(dict(plan, python=str(python))))
    return path


# ----------------------------------------------------------------------------------------
# Flamenco


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
    return f"""{FLAMENCO_MARK}, written by
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
    """JOB/flamenco/ctlab-<job>.js (flamenco_job_type); one there that ctlab did not write
    is refused first (check_bundles)."""
    check_bundles(job_dir, plan["job"], openjd=False, flamenco=True)
    folder = Path(job_dir) / FLAMENCO_DIR
    with os_errors(folder):
        folder.mkdir(exist_ok=True)
    path = folder / f"ctlab-{plan['job']}.js"
    write_text(path, flamenco_job_type(plan, Path(job_dir).absolute(), repo_root, python))
    return path
