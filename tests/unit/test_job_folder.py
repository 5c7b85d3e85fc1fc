"""A job folder is input (docs/bad-input.md, "Job folders"): plan.json, the completion
markers and whatever stands where ``task``, ``merge`` and ``plan`` write are read as a user's
files — schema-checked, never blocking, never replaced or removed unless ctlab wrote them.

Pure core (core/jobgraph/), no Blender: the checks, and the writes a task makes after its
render (its outputs staged and renamed, then its marker), on folders built here. Each test
failed on the code before this layer (noted per test); the Hypothesis layer feeds any JSON, at
any depth, as a plan or a marker, and any mix of files, folders, pipes and links where a task
writes. A mutation check: with ``plan_problems`` returning [] the plan properties fail (a
KeyError or a folder outside the job), and with ``owned_file`` accepting links the job-folder
property fails (the user's file behind a link is replaced)."""

import json
import os
import stat
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

from addon.core import files, jobgraph
from addon.core.errors import UserError

OUTPUTS = ("render.raw", "notes.txt", "log.txt")  # stand-ins: no image read-back
FOLDERS = ("cook_torrance", "principled")


def a_plan(folders=FOLDERS) -> dict:
    """A plan as ctlab writes it (jobgraph.make_plan), with stand-in task contents."""
    renders = [
        jobgraph.render_task(f, {"settings": {"f": f}, "inputs": {"hdri": "0" * 24}}, OUTPUTS)
        for f in folders
    ]
    return jobgraph.make_plan(
        "matrix", {"base": {"rows": 1}, "samples": 1}, {"ctlab": "t"}, renders, ("report.html",)
    )


def job(tmp_path, plan=None) -> Path:
    folder = tmp_path / "job"
    folder.mkdir()
    files.write_json(folder / "plan.json", plan or a_plan())
    return folder


def finish(job_dir: Path, task: dict) -> None:
    """What a task writes after its render: its outputs staged and renamed (core.files),
    then its marker (jobgraph.mark_done) — the paths checked first, as graph.run_task does."""
    jobgraph.check_task_paths(job_dir, task)
    (job_dir / task["folder"]).mkdir(parents=True, exist_ok=True)
    for rel in task["outputs"]:
        files.write_text(job_dir / rel, f"{task['id']} {rel}")
    jobgraph.mark_done(job_dir, task)


# ----------------------------------------------------------------------------------------
# plan.json


def test_a_plan_ctlab_wrote_passes_and_reads_back(tmp_path):
    p = a_plan()
    assert jobgraph.plan_problems(p) == []
    assert jobgraph.read_plan(job(tmp_path, p)) == p


@pytest.mark.parametrize(
    "edit, words",
    [
        # a task's folder pointed outside the job folder (before: ctlab task wrote there)
        (lambda p: p["tasks"][1].update(folder="../principled"), "'folder' is not a folder"),
        (lambda p: p["tasks"][1].update(folder="/tmp/x"), "'folder' is not a folder"),
        (lambda p: p["tasks"][1].update(folder=".tasks"), "'folder' is not a folder"),
        (lambda p: p["tasks"][1].update(outputs=["../../x/render.png"]), "'outputs' are not"),
        (lambda p: p["tasks"][0].pop("folder"), "'folder' is not a folder"),  # was KeyError
        (lambda p: p.pop("job"), "'job' is not a job name"),
        (lambda p: p.update(spec=[1, 2]), "'spec' is not an object"),  # was TypeError
        (lambda p: p["spec"].update(samples="4"), "'spec.samples'"),
        (lambda p: p["spec"].update(hdris="forest.exr"), "'spec.hdris'"),
        (lambda p: p["tasks"][0].update(id="../../x"), "no valid 'id'"),
        (lambda p: p["tasks"][0].update(depends="x"), "'depends' is not a list"),
        (lambda p: p["tasks"].append(dict(p["tasks"][0])), "repeats the id"),
        (lambda p: p["tasks"][1].update(folder="cook_torrance"), "repeats another task's"),
        (lambda p: p["tasks"].pop(), "0 merge tasks"),
        (lambda p: p.update(version=True), "plan version True"),
    ],
)
def test_an_edited_plan_is_one_line_naming_the_problem(tmp_path, edit, words):
    p = a_plan()
    edit(p)
    folder = job(tmp_path, p)
    with pytest.raises(UserError) as err:
        jobgraph.read_plan(folder)
    assert words in str(err.value) and "plan the job again" in str(err.value)


def test_a_plan_nested_very_deep_is_one_line(tmp_path):
    """Before: json.loads raised RecursionError (a traceback)."""
    folder = tmp_path / "job"
    folder.mkdir()
    nested = json.dumps(dict(a_plan(), x="X")).replace('"X"', "[" * 70 + "]" * 70)
    for text in ("[" * 100_000 + "]" * 100_000, nested):
        (folder / "plan.json").write_text(text)
        with pytest.raises(UserError, match="is not a readable plan"):
            jobgraph.read_plan(folder)


def test_a_plan_over_its_size_limit_is_refused_unread(tmp_path, monkeypatch):
    folder = job(tmp_path)
    monkeypatch.setattr(jobgraph.schema, "MAX_PLAN_BYTES", 100)
    with pytest.raises(UserError, match="over the 100"):
        jobgraph.read_plan(folder)


@pytest.mark.parametrize("what", ["fifo", "folder", "link-to-fifo"])
def test_a_plan_that_is_a_pipe_or_a_folder_never_blocks(tmp_path, what, alarm):
    """Before: a named pipe as plan.json hung ``task`` and ``merge``."""
    folder = tmp_path / "job"
    folder.mkdir()
    path = folder / "plan.json"
    if what == "fifo":
        os.mkfifo(path)
    elif what == "folder":
        path.mkdir()
    else:
        os.mkfifo(tmp_path / "pipe")
        path.symlink_to(tmp_path / "pipe")
    with pytest.raises(UserError, match="not a regular file"):
        jobgraph.read_plan(folder)


# ----------------------------------------------------------------------------------------
# Completion markers


@pytest.mark.parametrize(
    "marker, words",
    [
        ({"id": "X", "outputs": []}, "another version"),
        (None, "corrupt completion marker"),
        ("a string", "corrupt completion marker"),
        ([1, 2], "corrupt completion marker"),
        ("SAME-ID-LIST", "corrupt completion marker"),  # outputs a list (was AttributeError)
        ("SAME-ID-STRING", "corrupt completion marker"),  # a record a string
        ("SAME-ID-BYTES", "corrupt completion marker"),  # bytes not a number
    ],
)
def test_a_damaged_marker_is_a_task_to_re_run(tmp_path, marker, words):
    p = a_plan()
    folder = job(tmp_path, p)
    task = jobgraph.render_tasks(p)[0]
    finish(folder, task)
    good = json.loads(jobgraph.marker_path(folder, task).read_text())
    if marker == "SAME-ID-LIST":
        marker = dict(good, outputs=list(good["outputs"]))
    elif marker == "SAME-ID-STRING":
        marker = dict(good, outputs={k: "x" for k in good["outputs"]})
    elif marker == "SAME-ID-BYTES":
        marker = dict(good, outputs={k: dict(v, bytes="12") for k, v in good["outputs"].items()})
    jobgraph.marker_path(folder, task).write_text(json.dumps(marker))
    assert words in jobgraph.problem(folder, task)
    with pytest.raises(UserError, match=f"task {task['id']}"):
        jobgraph.check_complete(folder, p)


def test_a_marker_that_is_a_pipe_is_a_task_to_re_run(tmp_path, alarm):
    """Before: a named pipe as a completion marker hung ``merge``."""
    p = a_plan()
    folder = job(tmp_path, p)
    task = jobgraph.render_tasks(p)[0]
    finish(folder, task)
    marker = jobgraph.marker_path(folder, task)
    marker.unlink()
    os.mkfifo(marker)
    assert jobgraph.problem(folder, task) == "has a corrupt completion marker"
    # and the next run of the task refuses to replace it (ctlab did not write a pipe)
    with pytest.raises(UserError, match="named pipe"):
        jobgraph.check_task_paths(folder, task)
    assert stat.S_ISFIFO(os.lstat(marker).st_mode)


def test_an_output_replaced_by_a_link_is_not_done(tmp_path):
    p = a_plan()
    folder = job(tmp_path, p)
    task = jobgraph.render_tasks(p)[0]
    finish(folder, task)
    out = folder / task["outputs"][0]
    (tmp_path / "copy").write_bytes(out.read_bytes())
    out.unlink()
    out.symlink_to(tmp_path / "copy")  # the same bytes, but not a file the task wrote
    assert "a link stands there" in jobgraph.problem(folder, task)


# ----------------------------------------------------------------------------------------
# What stands where ctlab writes


def test_tasks_as_a_file_is_one_line_and_kept(tmp_path):
    """Before: ``.tasks`` being a file raised FileExistsError (a traceback)."""
    p = a_plan()
    folder = job(tmp_path, p)
    (folder / ".tasks").write_text("mine")
    task = jobgraph.render_tasks(p)[0]
    with pytest.raises(UserError, match=r"\.tasks is a file where ctlab keeps"):
        jobgraph.check_task_paths(folder, task)
    with pytest.raises(UserError, match="not ready to merge"):
        jobgraph.check_complete(folder, p)
    with pytest.raises(UserError, match=r"\.tasks is a file"):
        with jobgraph.merge_lock(folder):
            pass
    assert (folder / ".tasks").read_text() == "mine"


@pytest.mark.parametrize("what", ["file", "link", "fifo", "folder"])
def test_a_lock_ctlab_did_not_write_is_refused_and_left(tmp_path, what, alarm):
    folder = job(tmp_path)
    lock = folder / ".tasks" / "merge.lock"
    lock.parent.mkdir()
    (tmp_path / "user.txt").write_text("precious")
    {
        "file": lambda: lock.write_text("my notes"),
        "link": lambda: lock.symlink_to(tmp_path / "user.txt"),
        "fifo": lambda: os.mkfifo(lock),
        "folder": lambda: lock.mkdir(),
    }[what]()
    before = os.lstat(lock)
    with pytest.raises(UserError, match="not a merge lock ctlab wrote"):
        with jobgraph.merge_lock(folder):
            pass
    assert os.lstat(lock).st_ino == before.st_ino
    assert (tmp_path / "user.txt").read_text() == "precious"


def test_a_lock_that_cannot_be_made_is_one_line(tmp_path, monkeypatch):
    """Before: ``merge`` on a job folder the user cannot write raised PermissionError on
    merge.lock (the tests run as root, so the refusal is made by os.open here)."""
    folder = job(tmp_path)
    real = os.open

    def refuse(path, flags, *a):
        if str(path).endswith("merge.lock"):
            raise PermissionError(13, "Permission denied", str(path))
        return real(path, flags, *a)

    monkeypatch.setattr(os, "open", refuse)
    with pytest.raises(UserError, match=r"cannot use .*merge.lock: permission denied"):
        with jobgraph.merge_lock(folder):
            pass


def test_a_task_folder_that_is_a_link_is_refused(tmp_path):
    """A link in the job folder where a task writes would lead its outputs elsewhere."""
    p = a_plan()
    folder = job(tmp_path, p)
    users = tmp_path / "users"
    users.mkdir()
    (users / "render.png").write_text("precious")
    (folder / "principled").symlink_to(users)
    task = next(t for t in jobgraph.render_tasks(p) if t["folder"] == "principled")
    with pytest.raises(UserError, match="is a link where ctlab keeps"):
        jobgraph.check_task_paths(folder, task)
    assert (users / "render.png").read_text() == "precious"


@pytest.mark.parametrize("bundle", ["openjd", "flamenco"])
@pytest.mark.parametrize("what", ["user-file", "folder-is-file", "link-to-users-folder"])
def test_a_bundle_never_replaces_a_users_file(tmp_path, bundle, what):
    """Before: ``plan --openjd`` deleted a user's file at JOB/openjd/ctlab and put a link in
    its place; JOB/openjd being a file raised FileExistsError after plan.json was written."""
    folder = tmp_path / "job"
    folder.mkdir()
    users = tmp_path / "users"
    users.mkdir()
    place = folder / bundle
    target = place / ("ctlab" if bundle == "openjd" else "ctlab-matrix.js")
    if what == "user-file":
        place.mkdir()
        target.write_text("precious")
    elif what == "folder-is-file":
        place.write_text("precious")
    else:
        place.symlink_to(users)
    before = {p: p.read_bytes() for p in tmp_path.rglob("*") if p.is_file()}
    with pytest.raises(UserError, match="nothing was written"):
        jobgraph.check_bundles(folder, "matrix", bundle == "openjd", bundle == "flamenco")
    writer = jobgraph.write_openjd if bundle == "openjd" else jobgraph.write_flamenco
    with pytest.raises(UserError):
        writer(folder, a_plan(), files.PACKAGE_ROOT, "python3")
    assert {p: p.read_bytes() for p in tmp_path.rglob("*") if p.is_file()} == before
    assert not list(users.iterdir())


def test_the_bundles_ctlab_wrote_are_written_again(tmp_path):
    folder = tmp_path / "job"
    folder.mkdir()
    for _ in range(2):  # the second time over its own files
        jobgraph.write_openjd(folder, a_plan(), files.PACKAGE_ROOT, "python3")
        jobgraph.write_flamenco(folder, a_plan(), files.PACKAGE_ROOT, "python3")
    assert (folder / "openjd" / "ctlab" / "scripts" / "ctlab.py").is_file()
    assert sorted(p.name for p in (folder / "openjd").iterdir()) == ["ctlab", "template.json"]
    assert (folder / "flamenco" / "ctlab-matrix.js").read_text().startswith(jobgraph.FLAMENCO_MARK)


def test_a_log_ctlab_did_not_write_is_left(tmp_path):
    p = a_plan()
    folder = job(tmp_path, p)
    task = jobgraph.render_tasks(p)[0]
    (folder / ".tasks").mkdir()
    (tmp_path / "user.txt").write_text("precious")
    jobgraph.log_path(folder, task).symlink_to(tmp_path / "user.txt")
    with pytest.raises(UserError, match="is a link where ctlab writes a task's log"):
        jobgraph.open_log(folder, task)
    with pytest.raises(UserError, match="is a link where ctlab writes a task's log"):
        jobgraph.check_logs(folder, jobgraph.render_tasks(p))  # before any worker starts
    jobgraph.log_path(folder, task).unlink()
    jobgraph.log_path(folder, task).write_text("my notes")
    with pytest.raises(UserError, match="a file ctlab did not write"):
        jobgraph.open_log(folder, task)
    jobgraph.log_path(folder, task).unlink()
    for _ in range(2):  # its own log is replaced
        jobgraph.open_log(folder, task).close()
    assert (tmp_path / "user.txt").read_text() == "precious"


# ----------------------------------------------------------------------------------------
# Property tests (Hypothesis): any JSON as a plan or a marker; anything where a task writes

JSON = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats(allow_nan=False) | st.text(max_size=8),
    lambda inner: (
        st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=8), inner, max_size=4)
    ),
    max_leaves=30,
)
PLACES = ("tasks", "folder", "output", "marker")


def _replace_somewhere(data, path, value):
    """``data`` with the value at ``path`` (a list of keys or indices, followed as far as it
    goes) replaced by ``value``."""
    if not path or not isinstance(data, (dict, list)) or not data:
        return value
    key = path[0]
    if isinstance(data, dict):
        key = sorted(data)[key % len(data)] if isinstance(key, int) else key
        return dict(data, **{key: _replace_somewhere(data[key], path[1:], value)})
    key = key % len(data) if isinstance(key, int) else 0
    return data[:key] + [_replace_somewhere(data[key], path[1:], value)] + data[key + 1 :]


@settings(max_examples=150, deadline=None, suppress_health_check=list(HealthCheck))
@given(path=st.lists(st.integers(0, 7), max_size=5), value=JSON)
def test_any_edit_of_a_plan_reads_or_is_one_line(tmp_path_factory, path, value):
    """Whatever value stands anywhere in plan.json, reading it gives a plan whose every
    task folder and output stays inside the job folder, or one UserError line."""
    folder = tmp_path_factory.mktemp("plan")
    (folder / "plan.json").write_text(json.dumps(_replace_somewhere(a_plan(), path, value)))
    try:
        p = jobgraph.read_plan(folder)
    except UserError as exc:
        assert "\n" not in str(exc)
        return
    for t in jobgraph.render_tasks(p):
        for rel in [t["folder"], *t["outputs"]]:
            assert ".." not in rel.split("/") and not rel.startswith("/"), rel
        jobgraph.problem(folder, t)  # never raises


@settings(max_examples=150, deadline=None, suppress_health_check=list(HealthCheck))
@given(data=JSON)
def test_any_json_as_a_plan_or_a_marker_is_one_line(tmp_path_factory, data):
    folder = tmp_path_factory.mktemp("any")
    (folder / "plan.json").write_text(json.dumps(data))
    with pytest.raises(UserError):
        jobgraph.read_plan(folder)
    task = jobgraph.render_tasks(a_plan())[0]
    (folder / ".tasks").mkdir()
    jobgraph.marker_path(folder, task).write_text(json.dumps(data))
    why = jobgraph.problem(folder, task)
    assert why in ("has a corrupt completion marker",) or why.startswith("holds the output")


def make(path: Path, what: str, users: Path, root: Path) -> None:
    """Put a file, a folder, a pipe or a link at ``path``."""
    if what == "file":
        path.write_text("mine")
    elif what == "folder":
        path.mkdir()
    elif what == "fifo":
        os.mkfifo(path)
    else:
        path.symlink_to(
            {"link-to-file": users / "file", "link-to-folder": users}.get(what, root / "nowhere")
        )


KINDS = ("nothing", "file", "folder", "fifo", "link-to-file", "link-to-folder", "dangling")


@settings(max_examples=80, deadline=None, suppress_health_check=list(HealthCheck))
@given(st.fixed_dictionaries({place: st.sampled_from(KINDS) for place in PLACES}))
def test_whatever_stands_where_a_task_writes_no_users_file_changes(tmp_path_factory, kinds):
    """Files, folders, pipes and links at the task's folder, an output, ``.tasks`` and the
    marker: the task either refuses in one line before writing, or writes, and the user's
    files (outside, or behind a link) are byte-identical and no link was replaced."""
    root = tmp_path_factory.mktemp("jobfolder")
    p = a_plan()
    folder = job(root, p)
    task = jobgraph.render_tasks(p)[0]
    users = root / "users"
    users.mkdir()
    (users / "file").write_text("precious")
    places = {
        "tasks": folder / ".tasks",
        "folder": folder / task["folder"],
        "output": folder / task["outputs"][1],
        "marker": jobgraph.marker_path(folder, task),
    }
    for place, path in places.items():
        what = kinds[place]
        parent = {"output": "folder", "marker": "tasks"}.get(place)
        if what == "nothing" or (parent and kinds[parent] not in ("nothing", "folder")):
            continue  # a place below a link or a file: stays as it is
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            make(path, what, users, root)
        except OSError:
            continue  # a place below another non-folder: stays as it is
    links = {p: os.readlink(p) for p in folder.rglob("*") if p.is_symlink()}
    try:
        finish(folder, task)
    except UserError as exc:
        assert "\n" not in str(exc)
    else:
        assert not links  # no link stood anywhere it writes
        assert jobgraph.done(folder, task)
    assert (users / "file").read_text() == "precious"
    assert [p.name for p in users.iterdir()] == ["file"]
    assert {p: os.readlink(p) for p in folder.rglob("*") if p.is_symlink()} == links
