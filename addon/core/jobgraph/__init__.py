"""A batch job as a task graph, as data: independent render tasks and a merge task that
depends on them, written to ``JOB/plan.json`` (versioned, each task with its command line),
run one task at a time by any number of processes or farm workers, and merged into the same
outputs, in the same layout, as the job run in one process.

- A task's id is derived from its content (plan.content_id): its settings, the sample count,
  the model's and ctlab's versions, Blender's version and its inputs' content hashes (an
  HDRI's file hash, never its path), so a plan made elsewhere or later for other settings
  cannot pass for this one (``plan.py``: the plan, its tasks, where its records lie).
- The job folder is input (``schema.py``: plan.json and the markers read bounded, without
  blocking, and schema-checked; ``ownership.py``: ctlab writes only where nothing stands or
  what it wrote, through real folders).
- A render task writes its folder whole (core.files.atomic_paths, through the renderer) and
  then its completion marker ``JOB/.tasks/<folder>.json``: a task whose marker matches is done
  and a re-run does nothing; a task killed before its marker is retried alone. The merge
  checks every render task first and names, in one line, the tasks to re-run, under an
  exclusive lock file (``markers.py``).
- The farm bundles: the plan as an Open Job Description job template and as a Flamenco job
  type (``bundles.py``).

Pure Python: no bpy (the jobs layer, jobs/graph.py, fills in what a task renders). The names
the callers use are imported here: ``jobgraph.read_plan``, ``jobgraph.merge_lock`` ...
"""

from .bundles import (
    FLAMENCO_MARK,
    check_bundles,
    write_flamenco,
    write_openjd,
)
from .markers import LOCK_FILE, check_complete, done, mark_done, merge_lock, problem
from .ownership import (
    check_folders,
    check_logs,
    check_task_paths,
    open_log,
    os_errors,
    owned_file,
)
from .plan import (
    FORMAT,
    PLAN_VERSION,
    TASKS_DIR,
    content_id,
    find_task,
    log_path,
    make_plan,
    marker_path,
    plan_path,
    render_task,
    render_tasks,
)
from .schema import (
    MAX_PLAN_BYTES,
    plan_problems,
    read_json,
    read_plan,
    write_plan,
)

__all__ = [
    "FLAMENCO_MARK",
    "FORMAT",
    "LOCK_FILE",
    "MAX_PLAN_BYTES",
    "PLAN_VERSION",
    "TASKS_DIR",
    "check_bundles",
    "check_complete",
    "check_folders",
    "check_logs",
    "check_task_paths",
    "content_id",
    "done",
    "find_task",
    "log_path",
    "make_plan",
    "mark_done",
    "marker_path",
    "merge_lock",
    "open_log",
    "os_errors",
    "owned_file",
    "plan_path",
    "plan_problems",
    "problem",
    "read_json",
    "read_plan",
    "render_task",
    "render_tasks",
    "write_flamenco",
    "write_openjd",
    "write_plan",
]
