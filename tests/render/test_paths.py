"""The path gate (core/paths.py) on every input and output of the command line: paths that
Blender reinterprets, names longer than the system allows, a deep --out, inputs of every file
type (never blocking), an input where an output goes, --out inside the cache, a folder where
an output file goes; and its properties (Hypothesis) over paths, derived names, files of every
type and inputs against outputs. Each command-line case failed on the code before it. Most
checks happen before any render, so these tests render nothing."""

import os
import socket
from pathlib import Path

import pytest
from hypothesis import given, strategies as st

from helpers import FAST, TINY, listing, one_line
from addon.core import cache, paths
from addon.core.errors import UserError
from addon.jobs import cli

# The path gate: the same on every Blender series, so run on one
# (docs/testing.md, "Which tests run on both series").
pytestmark = pytest.mark.one_series

RENDER = ["render", "--shader", "nodes", "--view", "NdotL", *TINY]

# The rows of docs/bad-input.md that these tests hold (test_bad_input checks the table lists
# them and that each names a test here): ID -> the test.
CASES = {
    "lights-in-render-folder": "test_a_lights_file_in_a_matrix_render_folder_is_refused_before_any_render",  # noqa: E501
    "lights-stem-dots": "test_a_lights_stem_of_dots_stays_inside_out",
}


@pytest.mark.parametrize("option", ["--hdri", "--lights", "--out"])
@pytest.mark.parametrize("form", ["//sky.exr", "a\\b.exr"])
def test_paths_blender_reinterprets_are_refused(option, form, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    argv = RENDER + [option, form] + ([] if option == "--out" else ["--out", "o"])
    one_line(capsys, cli.main(argv), "Blender reads")
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
    one_line(capsys, cli.main(argv[where]), "longer than this system allows")


def test_a_deep_out_is_refused_before_any_work(tmp_path, capsys):
    """Blender's image writer truncates a path past FILE_MAX (1024 bytes) and writes
    elsewhere; an --out whose names would not fit is refused before anything is made."""
    deep = tmp_path.joinpath(*["d" * 200] * 5)  # about 1 KB
    before = listing(tmp_path)
    one_line(capsys, cli.main(RENDER + ["--out", str(deep)]), "longer than this system")
    assert listing(tmp_path) == before


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
    one_line(capsys, cli.main(argv), "not a regular file")
    assert not Path(out).exists()


def test_a_lights_file_where_an_output_goes_is_refused(tmp_path, capsys):
    """A --lights file inside --out named like an output (scene.json) used to be
    overwritten by the render."""
    out = tmp_path / "o"
    out.mkdir()
    lights = out / "scene.json"
    text = '[{"type": "POINT", "energy": 10, "location": [0, 0, 3]}]'
    lights.write_text(text)
    one_line(
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
    one_line(
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


def test_out_inside_the_cache_is_refused(tmp_path, capsys, monkeypatch):
    """An --out inside a cache entry was accepted; the next use "repaired" the entry and
    deleted the user's outputs. Nothing under the cache is an --out."""
    monkeypatch.setenv("CTLAB_CACHE", str(tmp_path / "cache"))
    entry = cache.build("entry-1", lambda stage: (stage / "a.txt").write_text("a"))
    for out in (entry / "o", tmp_path / "cache"):
        one_line(capsys, cli.main(RENDER + ["--out", str(out)]), "inside the cache folder")
    one_line(capsys, cli.main(["plot", "--out", str(entry / "p")]), "inside the cache")
    assert cache.intact(entry) and sorted(os.listdir(entry)) == ["a.txt", cache.MANIFEST]


def test_a_folder_where_an_output_file_goes_is_refused_before_any_render(
    tmp_path, capsys, monkeypatch
):
    """A folder render.png/ in --out used to be found after render.exr was moved in."""
    from addon.blender import renderer

    out = tmp_path / "o"
    (out / "render.png").mkdir(parents=True)
    monkeypatch.setattr(renderer, "render_result", lambda *a: pytest.fail("rendered"))
    one_line(capsys, cli.main(RENDER + ["--out", str(out)]), "a folder where this job writes")
    assert sorted(os.listdir(out)) == ["render.png"]


def _plot(out, *extra):
    return cli.main(["plot", "--smoothness", "0.3", *extra, "--out", str(out)])


def test_a_folder_where_a_plot_file_goes_is_refused_before_any_render(
    tmp_path, capsys, monkeypatch
):
    from addon.jobs import plot_job

    out = tmp_path / "p"
    (out / "albedo.svg").mkdir(parents=True)
    monkeypatch.setattr(plot_job, "evaluate_plot", lambda *a: pytest.fail("rendered"))
    one_line(
        capsys, _plot(out, "--compare", "g=smith_ggx_correlated"), "holds a folder named albedo.svg"
    )
    from addon.core.brdf_plot import PlotSettings
    from addon.core.plot_figures import planned_names

    names = planned_names(PlotSettings(compare=(("g", "smith_ggx_correlated"),)))
    assert "slice_g-smith_ggx_correlated.exr" in names or any("diff_" in n for n in names)


# ----------------------------------------------------------------------------------------
# Properties


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
