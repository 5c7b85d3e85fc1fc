"""Hardening II: every path, file, disk and signal a user can hit. One test (or a few) per
class of docs/bad-input.md "Paths, files, disks and signals", each of which failed on the
code before it, and property tests (Hypothesis) over paths, names, numbers in every Unicode
digit class and files of every type.
Most checks happen before any render, so most tests render nothing; the rest are tiny
(32 px, one sample, one sphere)."""

import errno
import json
import os
import resource
import signal
import socket
import subprocess
import sys
import time
import unicodedata
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

from helpers import ROOT
from addon.core import cache, files, paths
from addon.core.errors import UserError
from addon.core.hdri import write_float_exr
from addon.jobs import cli
from addon.jobs.cli.options import parse_grid, parse_vector

CTLAB = [sys.executable, str(ROOT / "scripts" / "ctlab.py")]
TINY = ["--grid", "1x1", "--size", "32", "--samples", "1"]
RENDER = ["render", "--shader", "nodes", "--view", "NdotL", *TINY]


# The rows of docs/bad-input.md that these tests hold (test_bad_input checks the table lists
# them): ID -> the test.
CASES = {
    "lights-in-render-folder": "test_a_lights_file_in_a_matrix_render_folder_is_refused_before_any_render",  # noqa: E501
    "lights-stem-dots": "test_a_lights_stem_of_dots_stays_inside_out",
    "plot-foreign-manifest": "test_a_plot_json_ctlab_did_not_write_deletes_nothing",
    "plot-changed-file": "test_a_plot_removes_its_own_earlier_files_and_leaves_changed_ones",
    "report-not-ctlabs": "test_only_a_report_ctlab_wrote_is_removed_before_a_run",
    "cache-foreign-file": "test_a_damaged_cache_entry_with_a_users_file_loses_nothing_of_theirs",
    "write-disk-full": "test_a_full_disk_fails_the_render_with_one_line_and_keeps_nothing",
    "write-error": "test_failed_writes_are_one_line_naming_the_file",
    "write-truncated": "test_a_truncated_image_is_never_renamed_into_place",
    "signal-osl-compile": "test_sigterm_while_the_osl_shader_compiles_leaves_nothing",
    "signal-pixel-grid": "test_a_signal_inside_a_registered_temporary_folder_leaves_nothing",
}


def test_each_documented_case_names_a_test_here():
    assert all(callable(globals().get(name)) for name in CASES.values()), CASES


def _one_line(capsys, code, expect=None):
    """The command failed as bad input: exit 2, exactly one error line, no traceback."""
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if line.strip()]
    assert code == cli.EXIT_BAD_INPUT, err
    assert len(lines) == 1 and lines[0].startswith("ctlab: error: "), err
    if expect:
        assert expect in lines[0], lines[0]
    return lines[0]


def _listing(root: Path) -> set:
    return set(root.rglob("*"))


def _hdri(path: Path, nan=False) -> Path:
    px = np.ones((16, 32, 3), np.float32)
    if nan:
        px[2, 3, 1] = np.nan
    write_float_exr(path, px)
    return path


# ----------------------------------------------------------------------------------------
# 1. The path gate


@pytest.mark.parametrize("option", ["--hdri", "--lights", "--out"])
@pytest.mark.parametrize("form", ["//sky.exr", "a\\b.exr"])
def test_paths_blender_reinterprets_are_refused(option, form, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    argv = RENDER + [option, form] + ([] if option == "--out" else ["--out", "o"])
    _one_line(capsys, cli.main(argv), "Blender reads")
    assert not any(tmp_path.iterdir())


@pytest.mark.parametrize("where", ["--hdri", "--lights", "bake", "scene"])
def test_a_name_over_255_bytes_is_one_line(where, tmp_path, capsys):
    name = str(tmp_path / ("é" * 130 + ".exr"))  # 260 bytes in UTF-8, 134 characters
    argv = {
        "--hdri": RENDER + ["--hdri", name, "--out", str(tmp_path / "o")],
        "--lights": RENDER + ["--lights", name, "--out", str(tmp_path / "o")],
        "bake": ["bake", name],
        "scene": ["scene", name, "--out", str(tmp_path / "o")],
    }
    _one_line(capsys, cli.main(argv[where]), "longer than this system allows")


def test_a_deep_out_is_refused_before_any_work(tmp_path, capsys):
    """Blender's image writer truncates a path past FILE_MAX (1024 bytes) and writes
    elsewhere; an --out whose names would not fit is refused before anything is made."""
    deep = tmp_path.joinpath(*["d" * 200] * 5)  # about 1 KB
    before = _listing(tmp_path)
    _one_line(capsys, cli.main(RENDER + ["--out", str(deep)]), "longer than this system")
    assert _listing(tmp_path) == before


_SOCKETS = []


@pytest.fixture(autouse=True)
def _no_socket_left():
    yield
    import shutil

    while _SOCKETS:
        s, folder = _SOCKETS.pop()
        s.close()
        shutil.rmtree(folder, ignore_errors=True)


def _special(kind: str, tmp_path: Path) -> str:
    path = tmp_path / f"special-{kind}.json"
    if kind == "fifo":
        os.mkfifo(path)
    elif kind == "folder":
        path.mkdir()
    elif kind == "device":
        return "/dev/zero"
    elif kind == "socket":  # AF_UNIX paths are short: a short folder
        import tempfile

        path = Path(tempfile.mkdtemp(prefix="s", dir="/tmp")) / "s.json"
        s = socket.socket(socket.AF_UNIX)
        s.bind(str(path))
        _SOCKETS.append((s, path.parent))
    elif kind == "link-to-folder":
        (tmp_path / "target").mkdir()
        path.symlink_to(tmp_path / "target")
    return str(path)


@pytest.mark.parametrize("kind", ["fifo", "folder", "device", "socket", "link-to-folder"])
@pytest.mark.parametrize("where", ["--hdri", "--lights", "bake", "scene"])
def test_inputs_are_regular_files_and_never_block(kind, where, tmp_path, capsys, alarm):
    """A FIFO as --lights used to hang for good; every input of every type other than a
    regular file is one line, at once."""
    path = _special(kind, tmp_path)
    out = str(tmp_path / "o")
    argv = {
        "--hdri": RENDER + ["--hdri", path, "--out", out],
        "--lights": RENDER + ["--lights", path, "--out", out],
        "bake": ["bake", path],
        "scene": ["scene", path, "--out", out],
    }[where]
    _one_line(capsys, cli.main(argv), "not a regular file")
    assert not Path(out).exists()


def test_a_lights_file_where_an_output_goes_is_refused(tmp_path, capsys):
    """A --lights file inside --out named like an output (scene.json) used to be
    overwritten by the render."""
    out = tmp_path / "o"
    out.mkdir()
    lights = out / "scene.json"
    text = '[{"type": "POINT", "energy": 10, "location": [0, 0, 3]}]'
    lights.write_text(text)
    _one_line(
        capsys,
        cli.main(RENDER + ["--lights", str(lights), "--out", str(out)]),
        "is an input of this job",
    )
    assert lights.read_text() == text and sorted(os.listdir(out)) == ["scene.json"]


def test_a_lights_file_in_a_matrix_render_folder_is_refused_before_any_render(
    tmp_path, capsys, monkeypatch
):
    from addon.jobs import pipeline

    out = tmp_path / "m"
    (out / "principled").mkdir(parents=True)
    lights = out / "principled" / "render.png"
    lights.write_text('[{"type": "POINT", "energy": 10}]')
    monkeypatch.setattr(pipeline, "render_one", lambda *a, **k: pytest.fail("rendered"))
    _one_line(
        capsys,
        cli.main(
            [
                "matrix",
                "--grid",
                "2x2",
                "--size",
                "32",
                "--samples",
                "1",
                "--lights",
                str(lights),
                "--out",
                str(out),
            ]
        ),
        "is an input of this job",
    )


def test_a_lights_stem_of_dots_stays_inside_out(tmp_path, monkeypatch):
    """A lights file named '...json' has the stem '..': the parity job's folder is named
    from it, and used to be the parent of --out."""
    from addon.jobs import graph, pipeline

    lights = tmp_path / "...json"
    lights.write_text('[{"type": "POINT", "energy": 10, "location": [0, 0, 3]}]')
    seen = {}

    def run_parity(base, hdris, samples, out, events, verbose, name=None, workers=1):
        seen.update(out=out, name=name)
        raise pipeline.Cancelled()

    monkeypatch.setattr(graph, "run_parity", run_parity)
    out = tmp_path / "p"
    assert (
        cli.main(["matrix", "--parity", "--lights", str(lights), "--out", str(out)])
        == cli.EXIT_CANCELLED
    )
    folder = (seen["out"] / seen["name"]).resolve()
    assert folder.parent == out.resolve(), seen


@pytest.mark.parametrize(
    "argv",
    [
        ["--grid", "²x2"],
        ["--grid", "2x٣"],
        ["--size", "٣٢"],
        ["--samples", "１"],
        ["--seed", "७"],
        ["--sun-strength", "٣"],
        ["--sun-dir", "0,0,١"],
        ["--albedo", "0.5,0.5,0.٥"],
        ["--size", "3_2"],
    ],
)
def test_numbers_take_ascii_digits_only(argv, tmp_path, capsys):
    """str.isdigit accepts '²' and int() refuses it (a traceback on 5.2); int() and float()
    accept other scripts' digits and '_': every number is ASCII digits, else one line."""
    _one_line(
        capsys,
        cli.main(["render", "--shader", "nodes", *TINY, *argv, "--out", str(tmp_path / "o")]),
    )
    assert not (tmp_path / "o").exists()


def test_plot_numbers_take_ascii_digits_only(tmp_path, capsys):
    _one_line(capsys, cli.main(["plot", "--metallic", "٠.5", "--out", str(tmp_path / "o")]))


def test_out_inside_the_cache_is_refused(tmp_path, capsys, monkeypatch):
    """An --out inside a cache entry was accepted; the next use "repaired" the entry and
    deleted the user's outputs. Nothing under the cache is an --out."""
    monkeypatch.setenv("CTLAB_CACHE", str(tmp_path / "cache"))
    entry = cache.build("entry-1", lambda stage: (stage / "a.txt").write_text("a"))
    for out in (entry / "o", tmp_path / "cache"):
        _one_line(capsys, cli.main(RENDER + ["--out", str(out)]), "inside the cache folder")
    _one_line(capsys, cli.main(["plot", "--out", str(entry / "p")]), "inside the cache")
    assert cache.intact(entry) and sorted(os.listdir(entry)) == ["a.txt", cache.MANIFEST]


def test_a_folder_where_an_output_file_goes_is_refused_before_any_render(
    tmp_path, capsys, monkeypatch
):
    """A folder render.png/ in --out used to be found after render.exr was moved in."""
    from addon.blender import renderer

    out = tmp_path / "o"
    (out / "render.png").mkdir(parents=True)
    monkeypatch.setattr(renderer, "render_result", lambda *a: pytest.fail("rendered"))
    _one_line(capsys, cli.main(RENDER + ["--out", str(out)]), "a folder where this job writes")
    assert sorted(os.listdir(out)) == ["render.png"]


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


def test_a_folder_where_a_plot_file_goes_is_refused_before_any_render(
    tmp_path, capsys, monkeypatch
):
    from addon.jobs import pipeline

    out = tmp_path / "p"
    (out / "albedo.svg").mkdir(parents=True)
    monkeypatch.setattr(pipeline, "evaluate_plot", lambda *a: pytest.fail("rendered"))
    _one_line(
        capsys, _plot(out, "--compare", "g=smith_ggx_correlated"), "holds a folder named albedo.svg"
    )
    from addon.core.brdf_plot import PlotSettings
    from addon.core.plot_figures import planned_names

    names = planned_names(PlotSettings(compare=(("g", "smith_ggx_correlated"),)))
    assert "slice_g-smith_ggx_correlated.exr" in names or any("diff_" in n for n in names)


def test_a_damaged_cache_entry_with_a_users_file_loses_nothing_of_theirs(tmp_path, monkeypatch):
    monkeypatch.setenv("CTLAB_CACHE", str(tmp_path / "cache"))
    entry = cache.build("entry-2", lambda stage: (stage / "a.txt").write_text("a"))
    (entry / "a.txt").write_text("damaged")
    (entry / "mine.exr").write_text("a user's file")
    with pytest.raises(UserError, match="which ctlab did not write"):
        cache.lookup("entry-2")
    assert (entry / "mine.exr").read_text() == "a user's file"
    (entry / "mine.exr").unlink()
    assert cache.lookup("entry-2") is None and not entry.exists()  # ours alone: rebuilt
    stranger = cache.cache_dir() / "entry-3"
    (stranger / "x").mkdir(parents=True)
    with pytest.raises(UserError, match="not a cache entry ctlab wrote"):
        cache.cached("entry-3", lambda stage: (stage / "a.txt").write_text("a"))
    assert (stranger / "x").is_dir()


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


# ----------------------------------------------------------------------------------------
# 4. An unwritable cache


def test_an_unwritable_cache_names_the_remedy(tmp_path, capsys, monkeypatch):
    """A cache folder that exists but cannot be written (another user's) used to be a
    PermissionError traceback. Root writes anywhere chmod allows, so as root a read-only
    system folder stands in."""
    folder = tmp_path / "cache"
    folder.mkdir()
    folder.chmod(0o555)
    if files.probe_writable(folder) is None:
        folder = Path("/sys/kernel")
        if not folder.is_dir() or files.probe_writable(folder) is None:
            pytest.skip("no unwritable folder here")
    monkeypatch.setenv("CTLAB_CACHE", str(folder))
    line = _one_line(
        capsys, cli.main(["bake", str(_hdri(tmp_path / "sky.exr"))]), "cache folder not usable"
    )
    assert "CTLAB_CACHE" in line and "preferences" in line


# ----------------------------------------------------------------------------------------
# 5. Signals at every phase leave nothing behind


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


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_a_signal_inside_a_registered_temporary_folder_leaves_nothing(sig, tmp_path):
    """The one cleanup path (jobs/signals.py) removes a pixel grid's temporary folder and a
    staged file in it, whatever the phase: the process ends at once with 130."""
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    proc = subprocess.Popen(
        [sys.executable, "-c", CHILD, str(ROOT)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=dict(os.environ, TMPDIR=str(tmp)),
    )
    assert proc.stdout.readline().strip() == "ready", proc.stderr.read()
    assert any(tmp.iterdir())
    proc.send_signal(sig)
    proc.communicate(timeout=30)
    assert proc.returncode == 130
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


# ----------------------------------------------------------------------------------------
# 6. One rule for a NaN/Inf HDRI


@pytest.mark.parametrize("job", ["render", "bake"])
def test_a_nan_hdri_is_refused_by_every_job(job, tmp_path, capsys):
    hdri = str(_hdri(tmp_path / "nan.exr", nan=True))
    argv = (
        RENDER + ["--hdri", hdri, "--out", str(tmp_path / "o")]
        if job == "render"
        else ["bake", hdri, "--out", str(tmp_path / "o")]
    )
    _one_line(capsys, cli.main(argv), "1 NaN/Inf pixel(s)")
    assert not (tmp_path / "o").exists()


# ----------------------------------------------------------------------------------------
# Properties

FAST = settings(
    max_examples=300,
    deadline=None,
    derandomize=True,
    database=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture],
)
names = st.text(st.characters(blacklist_categories=("Cs",)), max_size=300)


@FAST
@given(
    text=st.one_of(
        names,
        st.lists(names, max_size=8).map("/".join),
        st.lists(
            st.sampled_from(["..", ".", "//", "\\", "a", "é" * 100, "", "x" * 256, "\0"]),
            max_size=12,
        ).map("/".join),
    )
)
def test_the_gate_gives_a_safe_path_or_one_line(text):
    for output in (False, True):
        try:
            p = paths.clean(text, "--out", output=output)
        except UserError:
            continue
        s = os.fsencode(str(p))
        assert p.is_absolute() and str(p) == os.path.normpath(str(p))
        assert not str(p).startswith("//") and b"\\" not in s and b"\0" not in s
        assert all(len(part) <= 255 for part in s.split(b"/"))
        assert len(s) <= paths.MAX_PATH_BYTES - (paths.OUTPUT_RESERVE if output else 0)


@FAST
@given(text=names)
def test_derived_names_never_leave_their_folder(text, tmp_path_factory):
    name = paths.safe_name(text)
    assert name and name not in (".", "..") and "/" not in name and not name.startswith(".")
    assert len(name.encode()) <= 64 and name.isascii()
    base = Path("/out")
    assert Path(os.path.normpath(base / name)).parent == base


DIGITS = st.characters(categories=("Nd", "No", "Nl"))


@FAST
@given(
    digits=st.lists(st.one_of(DIGITS, st.sampled_from("0123456789")), min_size=1, max_size=4).map(
        "".join
    )
)
def test_numbers_in_every_unicode_digit_class(digits):
    """Accepted exactly when every digit is ASCII, in every parser of numbers."""
    ascii_only = all(c in "0123456789" for c in digits)
    for parse in (paths.ascii_int, paths.ascii_float):
        try:
            value = parse(digits)
        except ValueError:
            assert not ascii_only, digits
        else:
            assert ascii_only and value == int(digits), digits
    try:
        parse_grid(f"{digits}x1")
        assert ascii_only
    except UserError:
        assert not ascii_only
    try:
        parse_vector(f"{digits},0,1", 3, "sun direction")
        assert ascii_only
    except UserError:
        assert not ascii_only


def test_unicode_digit_classes_are_covered():
    """The strategy above reaches the classes named above (a sanity check on it)."""
    assert unicodedata.category("²") == "No" and unicodedata.category("٣") == "Nd"
    assert "²".isdigit() and not "²".isdecimal()


KINDS = [
    "file",
    "fifo",
    "folder",
    "device",
    "socket",
    "link-to-folder",
    "link-to-file",
    "missing",
    "dangling-link",
]


@pytest.mark.parametrize("kind", KINDS)
def test_files_of_every_type(kind, tmp_path, alarm):
    """Only a regular file (or a link to one) is an input; nothing blocks."""
    if kind in ("file", "link-to-file"):
        target = tmp_path / "f.json"
        target.write_text("[]")
        path = target
        if kind == "link-to-file":
            path = tmp_path / "l.json"
            path.symlink_to(target)
    elif kind == "missing":
        path = tmp_path / "none.json"
    elif kind == "dangling-link":
        path = tmp_path / "d.json"
        path.symlink_to(tmp_path / "none")
    else:
        path = Path(_special(kind, tmp_path))
    if kind in ("file", "link-to-file"):
        assert paths.read_bytes(path, "--lights") == b"[]"
    else:
        with pytest.raises(UserError) as info:
            paths.read_bytes(path, "--lights")
        assert (
            "not found" if kind in ("missing", "dangling-link") else "not a regular file"
        ) in str(info.value)


@FAST
@given(
    rel=st.lists(
        st.sampled_from(["a", "b", "..", ".", "render.exr", "out"]), min_size=1, max_size=5
    )
)
def test_inputs_are_never_at_under_or_over_outputs(rel):
    """check_job refuses every input related to an output by containment, and accepts
    every other pair."""
    out = Path("/w/out/render.exr")
    inp = Path(os.path.normpath(Path("/w/out", *rel)))
    related = inp == out or out in inp.parents or inp in out.parents
    try:
        paths.check_job([inp], [out])
        assert not related, inp
    except UserError:
        assert related, inp
