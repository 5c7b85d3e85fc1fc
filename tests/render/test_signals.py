"""Signals: SIGINT (Ctrl-C) and SIGTERM cancel every job at every phase, at once, with one
line and exit status 130, and leave nothing behind: no partial output, no staging folder in
the cache, nothing in the system's temporary folder (the OSL compile folder and a pixel grid's
folder are registered temporaries, jobs/signals.py); the main job keeps its finished renders.
Checked on real processes."""

import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from helpers import CTLAB, ROOT, TINY
from addon.core import files
from addon.core.compare import read_image
from addon.core.hdri import write_float_exr

# Signals and processes: the same on every Blender series, so run on one
# (docs/testing.md, "Which tests run on both series").
pytestmark = pytest.mark.one_series

# The rows of docs/bad-input.md that these tests hold (test_bad_input checks the table lists
# them and that each names a test here): ID -> the test.
CASES = {
    "signal-osl-compile": "test_sigterm_while_the_osl_shader_compiles_leaves_nothing",
    "signal-pixel-grid": "test_a_signal_inside_a_registered_temporary_folder_leaves_nothing",
    "killed-temp-folder": "test_a_killed_processs_temporary_folders_go_once_an_hour_old",
}


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


def _watch_for(tmp: Path, prefix: str, proc, timeout=120):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline and proc.poll() is None:
        if any(p.name.startswith(prefix) for p in tmp.iterdir()):
            return True
        time.sleep(0.002)
    return False


def test_sigterm_while_the_osl_shader_compiles_leaves_nothing(tmp_path):
    """SIGTERM while Cycles compiles the OSL shader used to leave ctlab-osl-*/tmp*.oso in
    $TMPDIR: the compile folder is now one of the registered temporaries."""
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    out = tmp_path / "o"
    proc = subprocess.Popen(
        CTLAB + ["render", "--shader", "osl", *TINY, "--out", str(out)],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
        env=dict(os.environ, TMPDIR=str(tmp)),
    )
    seen = _watch_for(tmp, "ctlab-osl-", proc)
    proc.send_signal(signal.SIGTERM)
    err = proc.communicate(timeout=60)[1]
    assert seen, "the compile folder never appeared"
    assert proc.returncode == 130, err[-2000:]
    assert not any(tmp.iterdir()), list(tmp.rglob("*"))
    assert not out.exists() or not any(out.iterdir())


CHILD = """
import sys, time
sys.path.insert(0, sys.argv[1])
from addon.core.files import atomic_path, temporary_folder
from addon.jobs import signals
signals.install()
with temporary_folder("ctlab-pixels-") as folder, atomic_path(folder / "pixels.exr") as tmp:
    tmp.write_bytes(b"half")
    print("ready", flush=True)
    time.sleep(60)
"""


def _ready_child(script: str, tmp_path: Path, *args, stderr=subprocess.PIPE):
    """A Python child running ``script`` (given the repository's root and ``args``) with its
    own $TMPDIR, once it has printed "ready": (that folder, the process)."""
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    proc = subprocess.Popen(
        [sys.executable, "-c", script, str(ROOT), *args],
        stdout=subprocess.PIPE,
        stderr=stderr,
        text=True,
        env=dict(os.environ, TMPDIR=str(tmp)),
    )
    assert proc.stdout.readline().strip() == "ready", proc.stderr and proc.stderr.read()
    return tmp, proc


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_a_signal_inside_a_registered_temporary_folder_leaves_nothing(sig, tmp_path):
    """The one cleanup path (jobs/signals.py) removes a pixel grid's temporary folder and a
    staged file in it, whatever the phase: the process ends at once with 130."""
    tmp, proc = _ready_child(CHILD, tmp_path)
    assert any(tmp.iterdir())
    proc.send_signal(sig)
    proc.communicate(timeout=30)
    assert proc.returncode == 130
    assert not any(tmp.iterdir()), list(tmp.rglob("*"))


def test_a_cancel_whose_line_cannot_be_written_still_ends_the_process(tmp_path):
    """Stderr on a full disk: the watcher's line fails to be written, and the process still
    ends with 130 with its temporaries gone (it used to leave the watcher dead, the signals
    blocked and a main thread that waits for the watcher: a process only SIGKILL ends)."""
    with open("/dev/full", "w") as full:
        tmp, proc = _ready_child(CHILD, tmp_path, stderr=full)
        proc.send_signal(signal.SIGTERM)
        proc.communicate(timeout=30)
    assert proc.returncode == 130
    assert not any(tmp.iterdir()), list(tmp.rglob("*"))


CHILD_FAILS_AFTER = """
import argparse, sys, time
sys.path.insert(0, sys.argv[1])
from addon.jobs import signals
signals.block()  # before bpy starts its threads, as scripts/ctlab.py does
from addon.core.errors import UserError
from addon.core.files import temporary_folder
import importlib
cli = importlib.import_module("addon.jobs.cli.main")

def work(args):
    with temporary_folder("ctlab-osl-") as folder:
        print("ready", flush=True)
        while folder.exists():
            time.sleep(0.001)
        if sys.argv[2] == "fails":
            raise UserError("the OSL shader failed to compile: its .oso is gone")

class Parser:
    def parse_args(self, argv):
        return argparse.Namespace(command="plan", func=work)

def slow_remove(path, _remove=signals._remove):  # a big session folder takes a while
    _remove(path)
    time.sleep(0.5)

cli.build_parser = Parser
signals._remove = slow_remove
signals.install()
cli.run_and_exit([])
"""


@pytest.mark.parametrize("end", ["fails", "returns"])
def test_an_error_the_cancel_causes_does_not_win_the_race(end, tmp_path):
    """The watcher removes the temporaries while the main thread runs on: work that fails
    because its folder went (Cycles' compile of the OSL shader, once in CI) raised a
    UserError that main() reported with exit status 2 before the watcher's exit 130; work
    that ends then exited 0. The main thread now yields to a cancel under way
    (cli.main.run_and_exit, the entry of scripts/ctlab.py and of the add-on's background
    job): 130 and the one cancel line."""
    tmp, proc = _ready_child(CHILD_FAILS_AFTER, tmp_path, end)
    proc.send_signal(signal.SIGTERM)
    err = proc.communicate(timeout=30)[1]
    assert proc.returncode == 130, err
    assert err.strip().splitlines() == ["ctlab: cancelled; finished outputs are kept"], err
    assert not any(tmp.iterdir()), list(tmp.rglob("*"))


def test_pixel_grid_and_compile_folders_are_registered_temporaries():
    with files.temporary_folder("ctlab-pixels-") as folder:
        assert folder in files.live_temporaries() and folder.is_dir()
    assert not folder.exists() and folder not in files.live_temporaries()
    import inspect
    from addon.blender import osl_shader, pixel_grid

    for module in (osl_shader, pixel_grid):
        source = inspect.getsource(module)
        assert "temporary_folder(" in source and "mkdtemp" not in source, module


def test_a_killed_processs_temporary_folders_go_once_an_hour_old(tmp_path, monkeypatch):
    """SIGKILL leaves a temporary folder (an OSL compile's, a pixel grid's) that nothing
    could remove: the next temporary_folder removes those of processes that no longer run,
    once an hour old, and nothing else: not a younger one, not a running process's, not a
    name ctlab does not write, not a file, not a link."""
    monkeypatch.setattr(files.tempfile, "tempdir", str(tmp_path))
    dead = subprocess.Popen(["true"])
    dead.wait()
    alive = os.getppid()
    old = time.time() - 2 * files.TEMP_FOLDER_STALE_SECONDS
    entries = {
        f"ctlab-osl-{dead.pid}-0123456789ab": (old, False),
        f"ctlab-pixels-{dead.pid}-ba9876543210": (old, False),
        f"ctlab-osl-{dead.pid}-00000000000f": (time.time() - 60, True),  # a minute old
        f"ctlab-osl-{alive}-0123456789ab": (old, True),
        f"ctlab-osl-{dead.pid}-0123456789ab.keep": (old, True),
        f"other-osl-{dead.pid}-0123456789ab": (old, True),
    }
    for name, (mtime, _) in entries.items():
        (tmp_path / name).mkdir()
        (tmp_path / name / "compiled.oso").write_text("bytecode")
        os.utime(tmp_path / name, (mtime, mtime))
    user_file = tmp_path / f"ctlab-osl-{dead.pid}-aaaaaaaaaaaa"
    user_file.write_text("a file")
    link = tmp_path / f"ctlab-osl-{dead.pid}-bbbbbbbbbbbb"  # to a user's folder: never followed
    link.symlink_to(tmp_path / f"other-osl-{dead.pid}-0123456789ab")
    for path in (user_file, link):
        os.utime(path, (old, old), follow_symlinks=False)
    with files.temporary_folder("ctlab-osl-") as folder:
        assert folder.name.startswith(f"ctlab-osl-{os.getpid()}-")
    kept = {p.name for p in tmp_path.iterdir()}
    assert kept == {name for name, (_, keep) in entries.items() if keep} | {
        user_file.name,
        link.name,
    }
    with pytest.raises(ValueError):
        with files.temporary_folder("ctlab_OSL"):
            pass


def test_a_file_written_while_the_cancel_removes_its_folder_goes_too(tmp_path, monkeypatch):
    """The watcher removes a temporary folder while the main thread runs on: a file the
    main thread adds between rmtree's listing and its rmdir (the OSL compile's output, seen
    once in CI) left the folder standing. The removal now tries again until it is gone."""
    from addon.jobs import signals

    folder = tmp_path / "ctlab-osl-x"
    folder.mkdir()
    (folder / "shader.osl").write_text("source")
    real, calls = shutil.rmtree, []

    def racing(path, ignore_errors=False):
        calls.append(path)
        if len(calls) == 1:  # the listing's files go, then the main thread writes one
            (Path(path) / "shader.osl").unlink()
            (Path(path) / "compiled.oso").write_text("bytecode")
            return  # rmdir failed, and ignore_errors kept it quiet
        return real(path, ignore_errors=ignore_errors)

    monkeypatch.setattr(signals.shutil, "rmtree", racing)
    signals._remove(folder)
    assert not folder.exists() and len(calls) == 2
