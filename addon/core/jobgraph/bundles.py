"""The farm bundles of a plan: an Open Job Description job template
(specificationVersion jobtemplate-2023-09: https://github.com/OpenJobDescription/
openjd-specifications/wiki/2023-09-Template-Schemas): job parameters defaulting to the
planned job (PATH ones relative to the template's folder, as the spec requires), a Render
step whose STRING task parameter is the task id, and a Report step depending on it; and a
Flamenco 3 job type. Each replaces only a bundle ctlab wrote."""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import stat
from pathlib import Path

from ..errors import UserError
from ..files import staging_name, write_json, write_text
from .ownership import describe, lstat, os_errors, owned_file, owned_folder, starts_with
from .plan import TASKS_DIR, canonical, render_tasks
from .schema import MAX_PLAN_BYTES, read_json

OPENJD_DIR = "openjd"
OPENJD_SPEC = "jobtemplate-2023-09"
FLAMENCO_DIR = "flamenco"
FLAMENCO_MARK = "// Flamenco job type for one planned Cook-Torrance Lab job"


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
        st = lstat(link)
        if st is not None and not (stat.S_ISLNK(st.st_mode) and _is_ctlab_link(link)):
            raise UserError(
                f"{link} is {describe(st.st_mode)} ctlab did not make, where it links "
                "Cook-Torrance Lab's folder; move it away (nothing was written)"
            )
        owned_file(folder / "template.json", "the job template", _is_template)
    if flamenco:
        folder = job_dir / FLAMENCO_DIR
        owned_folder(folder, "the Flamenco job type")
        owned_file(folder / f"ctlab-{job}.js", "the Flamenco job type", starts_with(FLAMENCO_MARK))


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
// `ctlab plan {plan['job']} --flamenco` (addon/core/jobgraph/bundles.py). Put it in the Manager's
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
