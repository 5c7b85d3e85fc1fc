"""The job folder's JSON read as input (a user, a farm or a broken tool may have edited it):
bounded, non-blocking reads; the schema of a plan and of a completion marker, every field
ctlab reads checked for its type and every path for staying inside the job folder; and
plan.json read and written."""

from __future__ import annotations

import json
import os
import re
from pathlib import Path

from ..errors import UserError
from ..files import write_json
from ..paths import read_bytes, safe_name
from .plan import FORMAT, PLAN_FILE, PLAN_VERSION, TASKS_DIR, marker_name, plan_path

# A plan and a marker are input: their size and nesting are bounded before they are parsed or
# walked.
MAX_PLAN_BYTES = 64 << 20
MAX_MARKER_BYTES = 1 << 20
MAX_DEPTH = 64  # a plan ctlab writes nests 6 levels deep (8 with lights)
MAX_TASKS = 4096
_ID = re.compile(r"[A-Za-z0-9_]{1,80}-[0-9a-f]{12}", re.ASCII)
_HEX64 = re.compile(r"[0-9a-f]{64}", re.ASCII)


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
