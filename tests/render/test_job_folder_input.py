"""Hardening III: ``ctlab plan``, ``task`` and ``merge`` take hostile job folders
and inputs like the other commands — one line on stderr and exit 2, the user's files
byte-identical, nothing written where a refusal is made, no hang, no traceback.

Each test failed on the code before it (noted per test). Most refuse before any render; the
two that run a task render one tiny Principled view (1x1 grid, 32 px, one sample). The pure
checks (schema, markers, locks, bundles) and their Hypothesis layer are in
tests/unit/test_job_folder.py."""

import json
import os
from pathlib import Path

import numpy as np
import pytest

from addon.core import jobgraph
from addon.core.hdri import write_float_exr
from addon.jobs import cli
from helpers import one_line

# Job folders as input: the same on every Blender series, so run on one
# (docs/testing.md, "Which tests run on both series").
pytestmark = pytest.mark.one_series

TINY = ["--grid", "1x1", "--size", "32", "--samples", "1"]

# The rows of docs/bad-input.md that these tests hold (test_bad_input checks the table lists
# them): ID -> the test.
CASES = {
    "plan-hdri-stem-dots": "test_an_hdri_stem_of_dots_plans_and_renders_inside_the_job",
    "plan-folder-edited": "test_a_plan_edited_to_write_elsewhere_is_refused",
    "plan-damaged": "test_a_damaged_plan_is_one_line_for_task_and_merge",
    "plan-bundle-users-file": "test_plan_bundles_never_replace_a_users_file",
    "job-fifo": "test_pipes_in_the_job_folder_never_hang_task_or_merge",
    "marker-damaged": "test_a_marker_of_the_wrong_shape_names_the_task_to_re_run",
    "tasks-not-folder": "test_tasks_as_a_file_is_one_line_for_task_and_merge",
    "merge-refused-writes-nothing": "test_a_refused_merge_writes_nothing",
    "merge-unwritable": "test_a_merge_that_cannot_take_its_lock_is_one_line",
    "merge-folder-link": "test_a_link_where_the_merge_writes_is_refused",
    "hdri-replaced-after-plan": "test_an_hdri_replaced_after_planning_is_refused",
    "hdri-changed-after-plan": "test_an_hdri_changed_after_planning_is_named",
    "workers-unicode-digit": "test_workers_takes_ascii_digits_only",
}


def test_each_documented_case_names_a_test_here():
    assert all(callable(globals().get(name)) for name in CASES.values()), CASES


def snapshot(root: Path) -> dict:
    """Every entry under ``root``: a file's bytes, a link's target, or the kind."""
    out = {}
    for p in sorted(root.rglob("*")):
        if p.is_symlink():
            out[p] = ("link", os.readlink(p))
        elif p.is_file():
            out[p] = p.read_bytes()
        else:
            out[p] = "folder" if p.is_dir() else "other"
    return out


def hdri(path: Path, value=1.0) -> Path:
    write_float_exr(path, np.full((16, 32, 3), value, np.float32))
    return path


def plan(out: Path, *extra) -> dict:
    assert cli.main(["plan", "matrix", *TINY, "--out", str(out), *extra]) == 0
    return jobgraph.read_plan(out)


def parity_plan(out: Path, sky: Path) -> dict:
    assert cli.main(["plan", "parity", *TINY, "--hdri", str(sky), "--out", str(out)]) == 0
    return jobgraph.read_plan(out)


def edit(job: Path, change) -> None:
    data = json.loads((job / "plan.json").read_text())
    change(data)
    (job / "plan.json").write_text(json.dumps(data))


# ----------------------------------------------------------------------------------------
# Names and paths in a plan


def test_an_hdri_stem_of_dots_plans_and_renders_inside_the_job(tmp_path, capsys):
    """An HDRI named '...exr' has the stem '..'; it named the parity run's folder, so its
    folders were ../cook_torrance and ../principled and ``ctlab task`` replaced the user's
    principled/render.png beside the job folder. The stem is made safe like a lights
    file's (core.paths.safe_name): the run is JOB/hdri/."""
    sky = hdri(tmp_path / "...exr")
    users = tmp_path / "principled"
    users.mkdir()
    (users / "render.png").write_bytes(b"the user's image")
    job = tmp_path / "job"
    p = parity_plan(job, sky)
    folders = [t["folder"] for t in jobgraph.render_tasks(p)]
    assert folders == ["hdri/cook_torrance", "hdri/principled"]
    task = jobgraph.render_tasks(p)[1]
    before = snapshot(users)
    assert cli.main(["task", str(job), task["id"]]) == 0, capsys.readouterr().err
    assert (job / "hdri" / "principled" / "render.png").is_file()
    assert snapshot(users) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["...exr", "job", "principled"]


def test_a_plan_edited_to_write_elsewhere_is_refused(tmp_path, capsys):
    """A parity task's folder (with the spec's run name) edited to lead out of the job
    folder: ``ctlab task`` wrote there (the task id does not hash the folder). Now every
    path of a plan is gated again at task and merge time; a link in the job folder leading
    elsewhere is refused too."""
    sky = hdri(tmp_path / "sky.exr")
    job = tmp_path / "job"
    p = parity_plan(job, sky)
    task = jobgraph.render_tasks(p)[1]
    outside = tmp_path / "x" / "principled"
    outside.mkdir(parents=True)
    (outside / "render.png").write_bytes(b"the user's image")
    before = snapshot(tmp_path)

    def escape(data):
        data["spec"]["name"] = "../x"
        for t in data["tasks"]:
            if t.get("kind") == "render":
                t["folder"] = t["folder"].replace("sky", "../x")
                t["outputs"] = [o.replace("sky", "../x") for o in t["outputs"]]

    edit(job, escape)
    before = snapshot(tmp_path)
    for argv in (["task", str(job), task["id"]], ["merge", str(job)]):
        one_line(capsys, cli.main(argv), "'folder' is not a folder inside the job folder")
    assert snapshot(tmp_path) == before
    # the folder kept, but a link to the user's folder in its place
    job2 = tmp_path / "job2"
    p = parity_plan(job2, sky)
    (job2 / "sky").symlink_to(outside.parent)
    task = jobgraph.render_tasks(p)[1]
    before = snapshot(tmp_path)
    one_line(capsys, cli.main(["task", str(job2), task["id"]]), "is a link where ctlab keeps")
    assert snapshot(tmp_path) == before


@pytest.mark.parametrize(
    "damage, words",
    [
        (lambda d: d.update(tasks=[[[[]]]] * 3), "task 1 is not an object"),
        (lambda d: d.update(x=json.loads("[" * 200 + "]" * 200)), "nested over"),
        (lambda d: d["tasks"][0].pop("folder"), "'folder' is not a folder"),  # was KeyError
        (lambda d: d.pop("job"), "'job' is not a job name"),
        (lambda d: d.pop("spec"), "'spec' is not an object"),
        (lambda d: d.update(spec="matrix"), "'spec' is not an object"),  # was TypeError
        (lambda d: d["spec"].update(base=[]), "'spec.base'"),
        (lambda d: d["spec"]["base"].update(width="wide"), "plan the job again"),
    ],
)
def test_a_damaged_plan_is_one_line_for_task_and_merge(tmp_path, capsys, damage, words):
    job = tmp_path / "job"
    task = jobgraph.render_tasks(plan(job))[0]
    edit(job, damage)
    (job / "deep.json").write_text("[" * 100_000 + "]" * 100_000)
    before = snapshot(tmp_path)
    for argv in (["task", str(job), task["id"]], ["merge", str(job)]):
        one_line(capsys, cli.main(argv), words)
    (job / "plan.json").write_text("[" * 100_000 + "]" * 100_000)  # was RecursionError
    one_line(capsys, cli.main(["merge", str(job)]), "is not a readable plan (nested too deep)")
    before[job / "plan.json"] = (job / "plan.json").read_bytes()
    assert snapshot(tmp_path) == before


def test_plan_bundles_never_replace_a_users_file(tmp_path, capsys):
    """``plan --openjd --out F`` with F/openjd/ctlab a user's file deleted it and put a link
    in its place; F/openjd a file raised FileExistsError after writing plan.json. Now both
    are refused before anything is written (the same for flamenco/)."""
    for where, flag in (
        ("openjd/ctlab", "--openjd"),
        ("openjd", "--openjd"),
        ("flamenco", "--flamenco"),
    ):
        job = tmp_path / where.replace("/", "_")
        (job / where).parent.mkdir(parents=True, exist_ok=True)
        (job / where).write_bytes(b"the user's file")
        before = snapshot(tmp_path)
        one_line(
            capsys,
            cli.main(["plan", "matrix", *TINY, "--out", str(job), flag]),
            "(nothing was written)",
        )
        assert snapshot(tmp_path) == before and not (job / "plan.json").exists()


# ----------------------------------------------------------------------------------------
# Pipes, damaged markers, the records folder


def test_pipes_in_the_job_folder_never_hang_task_or_merge(tmp_path, capsys, alarm):
    """A named pipe as plan.json hung ``task`` and ``merge``; one as a completion marker hung
    ``merge``. Every read of the job folder now checks for a regular file first and opens
    with O_NONBLOCK (core.paths.read_bytes)."""
    job = tmp_path / "job"
    p = plan(job)
    task = jobgraph.render_tasks(p)[0]
    (job / ".tasks").mkdir()
    os.mkfifo(jobgraph.marker_path(job, task))
    one_line(capsys, cli.main(["merge", str(job)]), f"{task['id']} (cook_torrance) has a corrupt")
    one_line(
        capsys,
        cli.main(["task", str(job), task["id"]]),
        "is a named pipe (FIFO) where ctlab writes a task's completion marker",
    )
    (job / "plan.json").unlink()
    os.mkfifo(job / "plan.json")
    for argv in (["task", str(job), task["id"]], ["merge", str(job)]):
        one_line(capsys, cli.main(argv), "is a named pipe (FIFO), not a regular file")


@pytest.mark.parametrize("shape", ["outputs-list", "record-string", "marker-string"])
def test_a_marker_of_the_wrong_shape_names_the_task_to_re_run(tmp_path, capsys, shape):
    """A marker whose outputs is a list, or whose record is a string, raised AttributeError
    in ``merge``; now it is a task to re-run, named with its command."""
    job = tmp_path / "job"
    p = plan(job)
    task = jobgraph.render_tasks(p)[0]
    (job / ".tasks").mkdir()
    marker = {"id": task["id"], "version": 1, "outputs": {o: "x" for o in task["outputs"]}}
    if shape == "outputs-list":
        marker["outputs"] = list(task["outputs"])
    elif shape == "marker-string":
        marker = task["id"]
    jobgraph.marker_path(job, task).write_text(json.dumps(marker))
    line = one_line(capsys, cli.main(["merge", str(job)]), "has a corrupt completion marker")
    assert f"ctlab task {job} {task['id']}" in line


def test_tasks_as_a_file_is_one_line_for_task_and_merge(tmp_path, capsys):
    """``.tasks`` being a file raised FileExistsError after the render; now the task refuses
    before it renders, and the merge names the tasks."""
    job = tmp_path / "job"
    task = jobgraph.render_tasks(plan(job))[0]
    (job / ".tasks").write_bytes(b"the user's file")
    before = snapshot(tmp_path)
    one_line(capsys, cli.main(["task", str(job), task["id"]]), ".tasks is a file where ctlab")
    one_line(capsys, cli.main(["merge", str(job)]), "not ready to merge")
    assert snapshot(tmp_path) == before


def test_a_refused_merge_writes_nothing(tmp_path, capsys):
    """A merge refused because tasks have not run created JOB/.tasks (its lock's folder)."""
    job = tmp_path / "job"
    plan(job)
    before = snapshot(tmp_path)
    one_line(capsys, cli.main(["merge", str(job)]), "not ready to merge")
    assert snapshot(tmp_path) == before


def test_a_merge_that_cannot_take_its_lock_is_one_line(tmp_path, capsys, monkeypatch):
    """A finished job folder the user cannot write: the merge raised PermissionError on
    merge.lock. The tests run as root (who may write anywhere), so the lock's open is made
    to fail as it does for a user; the tasks are marked done over placeholders."""
    job = tmp_path / "job"
    fake_done(job)
    real = os.open

    def refuse(path, flags, *a, **kw):
        if str(path).endswith(jobgraph.LOCK_FILE):
            raise PermissionError(13, "Permission denied", str(path))
        return real(path, flags, *a, **kw)

    monkeypatch.setattr(os, "open", refuse)
    before = snapshot(tmp_path)
    one_line(capsys, cli.main(["merge", str(job)]), "merge.lock: permission denied")
    assert snapshot(tmp_path) == before


def fake_done(job: Path) -> None:
    """A planned job whose render tasks are marked done over placeholder outputs (the
    merge's checks read only files; comparing them would fail later)."""
    for t in jobgraph.render_tasks(plan(job)):
        for rel in t["outputs"]:
            (job / rel).parent.mkdir(parents=True, exist_ok=True)
            (job / rel).write_text(rel)
        jobgraph.mark_done(job, t)


@pytest.mark.parametrize("where", ["compare", "plots"])
def test_a_link_where_the_merge_writes_is_refused(tmp_path, capsys, where):
    """A link in the job folder where the merge writes (a comparison's folder, the plots')
    led its metrics.json and diff.png into the user's folder, replacing their files there;
    now every folder the merge writes in is checked first."""
    job = tmp_path / "job"
    fake_done(job)
    users = tmp_path / "users"
    users.mkdir()
    (users / "metrics.json").write_bytes(b"the user's file")
    (job / where).symlink_to(users)
    before = snapshot(tmp_path)
    one_line(capsys, cli.main(["merge", str(job)]), f"{job / where} is a link where ctlab keeps")
    assert snapshot(tmp_path) == before


# ----------------------------------------------------------------------------------------
# The planned inputs


@pytest.mark.parametrize("what", ["fifo", "folder"])
def test_an_hdri_replaced_after_planning_is_refused(tmp_path, capsys, what, alarm):
    """An HDRI replaced by a named pipe after planning hung ``task``; by a folder, it raised
    IsADirectoryError. The planned HDRI passes the path gate again before it is hashed."""
    sky = hdri(tmp_path / "sky.exr")
    job = tmp_path / "job"
    task = jobgraph.render_tasks(plan(job, "--hdri", str(sky)))[0]
    sky.unlink()
    os.mkfifo(sky) if what == "fifo" else sky.mkdir()
    kind = "a named pipe (FIFO)" if what == "fifo" else "a folder"
    one_line(capsys, cli.main(["task", str(job), task["id"]]), f"HDRI {sky} is {kind}")
    assert not (job / task["folder"]).exists()


def test_an_hdri_changed_after_planning_is_named(tmp_path, capsys):
    """An HDRI whose pixels changed after planning was refused as "planned by another
    version or with other settings"; the refusal now names the HDRI."""
    sky = hdri(tmp_path / "sky.exr")
    job = tmp_path / "job"
    task = jobgraph.render_tasks(plan(job, "--hdri", str(sky)))[0]
    hdri(sky, 2.0)
    one_line(
        capsys,
        cli.main(["task", str(job), task["id"]]),
        f"HDRI {sky} changed since the job was planned",
    )
    assert not (job / task["folder"]).exists()


@pytest.mark.parametrize("value", ["١٠٠٠", "1_000", "３００", "²"])
def test_workers_takes_ascii_digits_only(tmp_path, capsys, value):
    """``--workers`` took digits of other scripts and '1_000' (int()); now it goes through
    the number parser of the other options (core.paths.ascii_int)."""
    code = cli.main(["matrix", *TINY, "--workers", value, "--out", str(tmp_path / "o")])
    one_line(capsys, code, f"argument --workers: invalid int value: '{value}'")
    assert not (tmp_path / "o").exists()
