"""Ownership and writes: ctlab writes only under --out and the cache, each output whole or not
at all (a full disk, a failed or short write is one line naming the file, and nothing half
written stays), standard JSON, and it deletes only what it wrote (a plot's earlier files, an
earlier report). Checks on real processes where a limit must apply to Blender; the renders are
tiny (32 px, one sample)."""

import errno
import json
import os
import resource
import signal
import subprocess

import numpy as np
import pytest

from helpers import CTLAB, TINY, listing
from addon.core import files
from addon.core.errors import UserError
from addon.core.hdri import write_float_exr
from addon.jobs import cli

# Where ctlab writes: the same on every Blender series, so run on one
# (docs/testing.md, "Which tests run on both series").
pytestmark = pytest.mark.one_series

RENDER = ["render", "--shader", "nodes", "--view", "NdotL", *TINY]
SMALL = ["--grid", "2x2", "--size", "32", "--samples", "1"]

# The rows of docs/bad-input.md that these tests hold (test_bad_input checks the table lists
# them and that each names a test here): ID -> the test.
CASES = {
    "plot-foreign-manifest": "test_a_plot_json_ctlab_did_not_write_deletes_nothing",
    "plot-changed-file": "test_a_plot_removes_its_own_earlier_files_and_leaves_changed_ones",
    "report-not-ctlabs": "test_only_a_report_ctlab_wrote_is_removed_before_a_run",
    "write-disk-full": "test_a_full_disk_fails_the_render_with_one_line_and_keeps_nothing",
    "write-error": "test_failed_writes_are_one_line_naming_the_file",
    "write-truncated": "test_a_truncated_image_is_never_renamed_into_place",
}


# ----------------------------------------------------------------------------------------
# 1. Where ctlab writes


def test_nothing_is_written_outside_out_and_the_cache(tmp_path, monkeypatch):
    """A render, a bake with --out and a compare write only below their --out (and the cache,
    here inside tmp_path too): the folder above is listed before and after."""
    monkeypatch.chdir(tmp_path)
    cache_dir = tmp_path / "cache"
    monkeypatch.setenv("CTLAB_CACHE", str(cache_dir))
    before = listing(tmp_path)
    a, b = tmp_path / "a", tmp_path / "b"
    assert (
        cli.main(["render", "--shader", "osl", "--ibl", "split_sum", *SMALL, "--out", str(a)]) == 0
    )
    assert cli.main(["render", "--shader", "nodes", *SMALL, "--out", str(b)]) == 0
    assert cli.main(["compare", str(a), str(b), "--out", str(tmp_path / "c")]) == 0
    new = {
        p
        for p in listing(tmp_path) - before
        if not any(p == d or d in p.parents for d in (a, b, tmp_path / "c", cache_dir))
    }
    assert not new, new


def test_identical_renders_compare_to_standard_json_with_a_null_psnr(tmp_path):
    out = tmp_path / "a"
    assert cli.main(["render", "--shader", "nodes", *SMALL, "--out", str(out)]) == 0
    assert cli.main(["compare", str(out), str(out), "--out", str(tmp_path / "c")]) == 0
    text = (tmp_path / "c" / "metrics.json").read_text()
    metrics = json.loads(text, parse_constant=lambda c: pytest.fail(f"non-standard {c}"))
    assert metrics["overall"]["psnr_db"] is None and metrics["overall"]["mae"] == 0.0


# ----------------------------------------------------------------------------------------
# 2. Ownership: ctlab deletes only what it wrote


def _plot(out, *extra):
    return cli.main(["plot", "--smoothness", "0.3", *extra, "--out", str(out)])


def test_a_plot_json_ctlab_did_not_write_deletes_nothing(tmp_path, capsys):
    out = tmp_path / "p"
    out.mkdir()
    mine = out / "notes.txt"
    mine.write_text("my notes")
    (out / "plot.json").write_text(json.dumps({"files": ["notes.txt", "plot.json"]}))
    assert _plot(out) == 0
    assert mine.read_text() == "my notes"
    assert "left alone" in capsys.readouterr().err


def test_a_plot_removes_its_own_earlier_files_and_leaves_changed_ones(tmp_path, capsys):
    """An earlier plot's extra views are removed when a new plot does not write them again,
    but only while they hold what that plot wrote (plot.json's sha256)."""
    out = tmp_path / "p"
    assert _plot(out, "--view", "D,F") == 0
    data = json.loads((out / "plot.json").read_text())
    from addon.core.brdf_plot import PlotSettings
    from addon.core.plot_figures import planned_names

    assert planned_names(PlotSettings(smoothness=0.3, views=("D", "F"))) == set(data["files"])
    views = [f for f in data["files"] if f.startswith("slice_") and f.endswith(".exr")]
    assert len(views) >= 2 and set(views) <= set(data["sha256"]), data["files"]
    edited = out / views[0]
    edited.write_bytes(edited.read_bytes() + b"edited")
    capsys.readouterr()
    assert _plot(out) == 0
    assert edited.exists()  # changed since: left alone
    assert not (out / views[1]).exists()  # still ctlab's: removed
    assert "left alone" in capsys.readouterr().err


def test_only_a_report_ctlab_wrote_is_removed_before_a_run(tmp_path):
    """A job removes an earlier run's report.html before it starts; a user's own page of
    that name is not ctlab's and stays (the job's own report replaces it only at the end)."""
    from addon.core.report import write_parity_report  # noqa: F401  (the writer's module)

    theirs = tmp_path / "report.html"
    theirs.write_text("<p>my page</p>")
    assert not files.forget_report(theirs) and theirs.exists()
    theirs.write_text(
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
        "<title>Cook-Torrance Lab: sphere matrix report</title>"
    )
    assert files.forget_report(theirs) and not theirs.exists()
    link = tmp_path / "link.html"
    link.symlink_to(tmp_path / "elsewhere.html")
    assert not files.forget_report(link) and link.is_symlink()


def test_a_rerun_removes_the_old_report_first(tmp_path, monkeypatch):
    """The report is written last; an earlier run's is removed when a job starts, so a job
    that stops half-way never leaves a report of old numbers beside new images."""
    out = tmp_path / "m"
    out.mkdir()
    (out / "report.html").write_text(
        "<!DOCTYPE html><html><head><title>Cook-Torrance Lab: "
        "sphere matrix report</title></head>an old run</html>"
    )
    from addon.jobs import pipeline

    def stop_at_the_first_render(*args, **kw):
        raise pipeline.Cancelled()

    monkeypatch.setattr(pipeline, "render_one", stop_at_the_first_render)
    assert (
        cli.main(["matrix", "--grid", "2x2", "--size", "32", "--samples", "1", "--out", str(out)])
        == cli.EXIT_CANCELLED
    )
    assert not (out / "report.html").exists()
    (out / "report.html").write_text("<p>a user's own page</p>")  # not ctlab's: kept
    assert (
        cli.main(["matrix", "--grid", "2x2", "--size", "32", "--samples", "1", "--out", str(out)])
        == cli.EXIT_CANCELLED
    )
    assert (out / "report.html").read_text() == "<p>a user's own page</p>"


# ----------------------------------------------------------------------------------------
# 3. Verified writes


def _limited(limit: int):
    def pre():
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))

    return pre


def _run(args, env=None, **kw):
    return subprocess.run(
        CTLAB + args,
        capture_output=True,
        text=True,
        timeout=300,
        env=dict(os.environ, **(env or {})),
        **kw,
    )


def test_a_full_disk_fails_the_render_with_one_line_and_keeps_nothing(tmp_path):
    """Under a file-size limit Blender's save_render writes a truncated render.exr and says
    nothing; it used to be renamed into place and reported as done."""
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    env = {"TMPDIR": str(tmp)}
    warm = _run(RENDER + ["--out", str(tmp_path / "warm")], env)  # the cache, unlimited
    assert warm.returncode == 0, warm.stderr
    size = (tmp_path / "warm" / "render.exr").stat().st_size
    out = tmp_path / "o"
    p = _run(RENDER + ["--out", str(out)], env, preexec_fn=_limited(size // 2))
    lines = [line for line in p.stderr.splitlines() if line.strip()]
    assert p.returncode == 2 and len(lines) == 1, p.stderr
    assert "render.exr" in lines[0] and "Traceback" not in p.stderr
    assert not out.exists() or not any(out.iterdir()), list(out.iterdir())
    assert not any(tmp.iterdir()), list(tmp.iterdir())
    # compare: diff.png or metrics.json (a few hundred bytes) does not fit in 150; both
    # are written together, so neither stays
    c = _run(
        ["compare", str(tmp_path / "warm"), str(tmp_path / "warm"), "--out", str(tmp_path / "c")],
        env,
        preexec_fn=_limited(150),
    )
    lines = [line for line in c.stderr.splitlines() if line.strip()]
    assert c.returncode == 2 and len(lines) == 1, c.stderr
    assert "diff.png" in lines[0] or "metrics.json" in lines[0], lines
    assert not (tmp_path / "c").exists() or not any((tmp_path / "c").iterdir())


@pytest.mark.parametrize("code", [errno.ENOSPC, errno.EFBIG, errno.EDQUOT, errno.EACCES])
def test_failed_writes_are_one_line_naming_the_file(code, tmp_path):
    target = tmp_path / "metrics.json"

    def fail(*_):
        raise OSError(code, os.strerror(code))

    with pytest.raises(UserError) as info:
        with files.atomic_path(target) as tmp:
            tmp.write_text("{")
            fail()
    assert str(target) in str(info.value) and "\n" not in str(info.value)
    assert os.listdir(tmp_path) == []


def test_a_truncated_image_is_never_renamed_into_place(tmp_path):
    good = tmp_path / "good.exr"
    write_float_exr(good, np.random.default_rng(1).random((32, 32, 3)).astype(np.float32))
    data = good.read_bytes()
    target = tmp_path / "render.exr"
    with pytest.raises(UserError, match="reads back truncated or corrupt"):
        with files.atomic_path(target) as tmp:
            tmp.write_bytes(data[: len(data) // 2])
    with pytest.raises(UserError, match="empty"):
        with files.atomic_path(tmp_path / "diff.png") as tmp:
            tmp.write_bytes(b"")
    assert sorted(os.listdir(tmp_path)) == ["good.exr"]
