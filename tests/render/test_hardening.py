"""The command line's promises under hostile conditions: negative values parse, a signal is a
cancel (also in the middle of a render), a damaged cache entry is rebuilt and never used,
nothing is written outside --out and the cache, and no job leaves files in the system's
temporary folder. Signals and leftovers are checked on real processes."""

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from helpers import ROOT
from addon.core import cache, ibl_bake
from addon.core.compare import read_image
from addon.core.hdri import write_float_exr
from addon.jobs import cli

CTLAB = [sys.executable, str(ROOT / "scripts" / "ctlab.py")]
SMALL = ["--grid", "2x2", "--size", "32", "--samples", "1"]


def _listing(root: Path) -> set:
    return set(root.rglob("*"))


def test_negative_values_parse_and_render(tmp_path, capsys):
    """The documented syntax with negative components, as the add-on's default Sun has them:
    argparse used to read "-0.45,..." as an option ("expected one argument")."""
    out = tmp_path / "out"
    code = cli.main(
        [
            "render",
            "--shader",
            "nodes",
            "--view",
            "NdotL",
            *SMALL,
            "--out",
            str(out),
            "--sun-dir",
            "-0.45,-0.55,0.70",
            "--hdri-rotation",
            "-1e-05",
        ]
    )
    assert code == 0, capsys.readouterr().err
    scene = json.loads((out / "scene.json").read_text())
    want = np.array([-0.45, -0.55, 0.70]) / np.linalg.norm([-0.45, -0.55, 0.70])
    np.testing.assert_allclose(scene["sun"]["to_light"], want, rtol=1e-6)
    assert scene["hdri_rotation_deg"] == pytest.approx(-1e-05)


def test_nothing_is_written_outside_out_and_the_cache(tmp_path, monkeypatch):
    """A render, a bake with --out and a compare write only below their --out (and the cache,
    here inside tmp_path too): the folder above is listed before and after."""
    monkeypatch.chdir(tmp_path)
    cache_dir = tmp_path / "cache"
    monkeypatch.setenv("CTLAB_CACHE", str(cache_dir))
    before = _listing(tmp_path)
    a, b = tmp_path / "a", tmp_path / "b"
    assert (
        cli.main(["render", "--shader", "osl", "--ibl", "split_sum", *SMALL, "--out", str(a)]) == 0
    )
    assert cli.main(["render", "--shader", "nodes", *SMALL, "--out", str(b)]) == 0
    assert cli.main(["compare", str(a), str(b), "--out", str(tmp_path / "c")]) == 0
    new = {
        p
        for p in _listing(tmp_path) - before
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


def test_a_damaged_cache_entry_is_rebuilt_not_used(tmp_path, monkeypatch):
    """Truncate one cached level, change another's content: the next bake finds both by the
    manifest, builds the entry again, and renders the same values as before the damage."""
    monkeypatch.setenv("CTLAB_CACHE", str(tmp_path / "cache"))
    hdri = tmp_path / "sky.exr"
    rng = np.random.default_rng(3)
    write_float_exr(hdri, rng.gamma(1.0, 1.0, (64, 128, 3)).astype(np.float32))
    folder = ibl_bake.bake(hdri)
    assert cache.intact(folder)
    first = tmp_path / "first"
    assert (
        cli.main(
            [
                "render",
                "--shader",
                "nodes",
                "--view",
                "indirect",
                *SMALL,
                "--pixel-centres",
                "--hdri",
                str(hdri),
                "--out",
                str(first),
            ]
        )
        == 0
    )
    level = folder / ibl_bake.level_file(2)
    level.write_bytes(level.read_bytes()[:100])  # truncated
    assert not cache.intact(folder)
    again = ibl_bake.bake(hdri)
    assert again == folder and cache.intact(again)
    assert (folder / ibl_bake.level_file(2)).stat().st_size > 100
    second = tmp_path / "second"
    write_float_exr(folder / ibl_bake.level_file(3), np.zeros((32, 64, 3), np.float32))  # changed
    assert (
        cli.main(
            [
                "render",
                "--shader",
                "nodes",
                "--view",
                "indirect",
                *SMALL,
                "--pixel-centres",
                "--hdri",
                str(hdri),
                "--out",
                str(second),
            ]
        )
        == 0
    )
    # the same to float precision (a rebuilt bake's FFTs may round differently: 6e-6 seen),
    # where a level read as damaged (zeros, or a truncated file) changes values by far more
    np.testing.assert_allclose(
        read_image(second / "render.exr"), read_image(first / "render.exr"), rtol=1e-4, atol=1e-6
    )


def test_a_dead_processs_staging_folder_is_removed(tmp_path, monkeypatch):
    """A bake killed half-way leaves .NAME.<pid>-<hex>.partial; the next run that writes to
    the cache removes it when that process is gone (a live one's is left alone)."""
    monkeypatch.setenv("CTLAB_CACHE", str(tmp_path / "cache"))
    root = cache.cache_dir()
    dead = subprocess.run(
        [sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True
    ).stdout.strip()
    stale = root / f".ibl-v3-x.{dead}-0123abcd.partial"
    (stale / "specular_0.exr").parent.mkdir(parents=True)
    (stale / "specular_0.exr").write_bytes(b"half")
    alive = root / f".ibl-v3-y.{os.getppid()}-0123abcd.partial"
    alive.mkdir()
    cache.cache_dir()
    assert not stale.exists() and alive.exists()


def _start(args, env=None, **kw):
    env = dict(os.environ, PYTHONUNBUFFERED="1", **(env or {}))
    return subprocess.Popen(
        CTLAB + args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env, **kw
    )


def _wait_for(proc, text, timeout=180):
    """Read the child's stdout until a line holds ``text``."""
    deadline = time.monotonic() + timeout
    lines = []
    while time.monotonic() < deadline:
        line = proc.stdout.readline()
        if not line:
            break
        lines.append(line)
        if text in line:
            return lines
    raise AssertionError(f"never saw {text!r}: {''.join(lines)}")


def _cancelled(proc, started):
    out, err = proc.communicate(timeout=60)
    seconds = time.monotonic() - started
    assert proc.returncode == 130, (proc.returncode, err[-2000:])
    lines = [line for line in err.splitlines() if line.strip()]
    assert lines == ["ctlab: cancelled; finished outputs are kept"], err[-2000:]
    return seconds


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_a_signal_cancels_a_render_within_seconds(tmp_path, sig):
    """A 256-sample OSL render takes tens of seconds on two cores; a signal two seconds in
    stops it at once (Cycles used to swallow Ctrl-C and render on): exit 130, one line, no
    output and no temporary file in --out or the system's temporary folder."""
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    out = tmp_path / "out"
    proc = _start(
        [
            "render",
            "--shader",
            "osl",
            "--grid",
            "3x3",
            "--size",
            "192",
            "--samples",
            "256",
            "--out",
            str(out),
        ],
        env={"TMPDIR": str(tmp)},
    )
    _wait_for(proc, "rendering")
    time.sleep(2.0)
    proc.send_signal(sig)
    assert _cancelled(proc, time.monotonic()) < 5
    assert not out.exists() or not any(out.iterdir()), list(out.iterdir())
    assert not any(tmp.iterdir()), list(tmp.iterdir())


def test_sigterm_during_the_main_job_keeps_the_finished_renders(tmp_path):
    out = tmp_path / "m"
    proc = _start(["matrix", "--grid", "2x2", "--size", "32", "--samples", "2", "--out", str(out)])
    _wait_for(proc, "[2/")
    proc.send_signal(signal.SIGTERM)
    _cancelled(proc, time.monotonic())
    first = out / "cook_torrance"
    assert sorted(p.name for p in first.iterdir()) == ["render.exr", "render.png", "scene.json"]
    read_image(first / "render.exr")  # whole
    assert not [p for p in out.rglob("*") if "partial" in p.name]
    assert not (out / "report.html").exists()


def test_ctrl_c_during_a_bake_leaves_no_staging_folder(tmp_path):
    """Level 1 of a bake is a 512-wide convolution (about a second on two cores, whatever the
    source's size): Ctrl-C as it starts ends the bake with one line, and the cache holds no
    half-written entry (its staging folder is removed)."""
    cache_dir = tmp_path / "cache"
    hdri = tmp_path / "sky.exr"
    write_float_exr(hdri, np.random.default_rng(9).random((1024, 2048, 3)).astype(np.float32))
    proc = _start(["bake", str(hdri)], env={"CTLAB_CACHE": str(cache_dir)})
    _wait_for(proc, "specular level 1")
    proc.send_signal(signal.SIGINT)
    assert _cancelled(proc, time.monotonic()) < 5
    leftovers = [p.name for p in cache_dir.rglob("*") if "partial" in p.name]
    assert not leftovers, leftovers


def test_ctrl_c_during_a_plot_writes_nothing(tmp_path):
    """A plot writes its files together at the end: Ctrl-C after its first render leaves
    --out without a file (and no temporary), exit 130, one line."""
    out = tmp_path / "plot"
    proc = _start(
        [
            "plot",
            "--compare",
            "g=smith_ggx_correlated,energy=compensated",
            "--view",
            "D,F,G,NdotL",
            "--out",
            str(out),
        ]
    )
    _wait_for(proc, "[2/")
    proc.send_signal(signal.SIGINT)
    assert _cancelled(proc, time.monotonic()) < 5
    assert not out.exists() or not any(out.iterdir()), list(out.iterdir())


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
