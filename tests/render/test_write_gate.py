"""The write gate of folders that are also the user's (addon/core/gate.py): an export into a
project folder never replaces a file ctlab did not write (nor one it wrote and the user
changed since), never writes through a link, checks and decodes every texture before the first
byte, and lands all its files or none. ``--force`` (the Overwrite option) replaces the user's
regular files of the same names, still never through a link. Each test fails on the export
before the gate (it copied over any file of the same name and followed textures/ as a link)."""

import errno
import hashlib
import os
import pathlib
import subprocess
import sys

import numpy as np
import pytest

from helpers import ROOT, tiny_hdri
from addon.blender.material_export import TextureFile
from addon.core import compare, gate
from addon.core.errors import UserError
from addon.core.export import network
from addon.jobs.export_job import write_export

CTLAB = [sys.executable, str(ROOT / "scripts" / "ctlab.py")]

# Where ctlab writes: the same on every Blender series (docs/testing.md).
pytestmark = pytest.mark.one_series

CASES = {
    "export-users-file": "test_a_users_file_of_the_same_name_is_refused_and_kept",
    "export-changed-file": "test_a_file_ctlab_wrote_and_the_user_changed_is_refused",
    "export-textures-link": "test_textures_as_a_link_is_refused_and_nothing_written_through_it",
    "export-texture-damaged": "test_a_damaged_texture_is_named_and_nothing_is_written",
    "export-record-foreign": "test_a_foreign_file_in_the_records_place_is_refused",
    "export-tmpdir-full": "test_a_full_tmpdir_while_decoding_a_packed_map_is_one_line",
    "bake-users-file": "test_bake_out_keeps_a_users_file_before_baking",
}


def _digest(path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _tree(folder):
    """Every entry below ``folder`` with its content's digest (links as their target)."""
    out = {}
    for p in sorted(folder.rglob("*")):
        rel = p.relative_to(folder).as_posix()
        if p.is_symlink():
            out[rel] = "-> " + os.readlink(p)
        elif p.is_file():
            out[rel] = _digest(p)
        else:
            out[rel] = "/"
    return out


@pytest.fixture
def textured(tmp_path):
    """A material with an albedo texture (a file) and its texture list."""
    src = tmp_path / "src" / "paint.png"
    src.parent.mkdir()
    compare.write_png(src, np.full((4, 4, 3), 0.5))
    mat = network.Material("Paint", textures={"albedo": network.Texture("textures/paint.png")})
    return [mat], [TextureFile("textures/paint.png", source=str(src))]


def test_a_users_file_of_the_same_name_is_refused_and_kept(tmp_path, textured):
    """A project folder holding the user's own paint.png and Paint.mtlx: refused in one line
    naming the file, both kept byte for byte, nothing else written; with force, replaced."""
    materials, files_ = textured
    out = tmp_path / "project"
    (out / "textures").mkdir(parents=True)
    (out / "textures" / "paint.png").write_bytes(b"the user's painting")
    (out / "Paint.mtlx").write_text("<the user's own graph/>")
    before = _tree(out)
    with pytest.raises(UserError) as err:
        write_export(materials, files_, "materialx", out, "x")
    assert "did not write" in str(err.value) and "\n" not in str(err.value)
    assert str(out / "Paint.mtlx") in str(err.value) or "paint.png" in str(err.value)
    assert _tree(out) == before
    (out / "Paint.mtlx").unlink()  # only the texture is the user's now
    with pytest.raises(UserError, match="paint.png is a file ctlab did not write"):
        write_export(materials, files_, "materialx", out, "x")
    assert sorted(_tree(out)) == ["textures", "textures/paint.png"]
    written = write_export(materials, files_, "materialx", out, "x", force=True)
    assert {p.name for p in written} == {"paint.png", "Paint.mtlx"}
    assert (out / "textures" / "paint.png").read_bytes() == (
        tmp_path / "src" / "paint.png"
    ).read_bytes()


def test_a_file_ctlab_wrote_and_the_user_changed_is_refused(tmp_path, textured):
    """A second export replaces the files the first wrote (the record lists them with their
    hashes); once the user edits one, it is theirs: refused, and the edit kept."""
    materials, files_ = textured
    out = tmp_path / "out"
    write_export(materials, files_, "materialx", out, "x")
    write_export(materials, files_, "materialx", out, "x")  # its own files: replaced
    (out / "Paint.mtlx").write_text("<edited by hand/>")
    with pytest.raises(UserError, match="Paint.mtlx is a file ctlab did not write"):
        write_export(materials, files_, "materialx", out, "x")
    assert (out / "Paint.mtlx").read_text() == "<edited by hand/>"


def test_textures_as_a_link_is_refused_and_nothing_written_through_it(tmp_path, textured):
    """DIR/textures a link to the user's library: refused (even with force), the library
    untouched, nothing written into DIR either."""
    materials, files_ = textured
    library = tmp_path / "library"
    library.mkdir()
    (library / "paint.png").write_bytes(b"the library's own paint")
    out = tmp_path / "out"
    out.mkdir()
    (out / "textures").symlink_to(library)
    before, lib_before = _tree(out), _tree(library)
    for force in (False, True):
        with pytest.raises(UserError, match="textures is a link where ctlab keeps"):
            write_export(materials, files_, "materialx", out, "x", force=force)
    assert _tree(out) == before and _tree(library) == lib_before


def test_a_damaged_texture_is_named_and_nothing_is_written(tmp_path, textured):
    """The second of two textures is truncated: the message names that input (not an
    output), and the first texture is not left in --out: no file at all is written."""
    materials, files_ = textured
    bad = tmp_path / "src" / "broken.png"
    good = (tmp_path / "src" / "paint.png").read_bytes()
    bad.write_bytes(good[: len(good) // 2])
    mat = network.Material("Broken", textures={"albedo": network.Texture("textures/broken.png")})
    files_ = files_ + [TextureFile("textures/broken.png", source=str(bad))]
    out = tmp_path / "out"
    with pytest.raises(UserError) as err:
        write_export(materials + [mat], files_, "materialx", out, "x")
    message = str(err.value)
    assert f"texture {bad} is not a readable image" in message, message
    assert not out.exists()


def test_a_foreign_file_in_the_records_place_is_refused(tmp_path, textured):
    """A file named like the record that ctlab did not write (not its JSON) is never taken
    for ctlab's record, nor replaced."""
    materials, files_ = textured
    out = tmp_path / "out"
    out.mkdir()
    (out / gate.RECORD).write_text('{"files": {"Paint.mtlx": "0"}}')
    with pytest.raises(UserError, match="is not ctlab's record"):
        write_export(materials, files_, "materialx", out, "x")
    assert [p.name for p in out.iterdir()] == [gate.RECORD]


def test_a_full_tmpdir_while_decoding_a_packed_map_is_one_line(tmp_path, monkeypatch):
    """A packed map is decoded through a private temporary file: a TMPDIR that is full (the
    write of that copy fails with ENOSPC) is one line naming TMPDIR, not a traceback; nothing
    is written into --out and the temporary folder is gone."""
    src = tmp_path / "r.png"
    compare.write_png(src, np.full((2, 3, 3), 0.7))
    data = src.read_bytes()
    mat = network.Material(
        "R", textures={"smoothness": network.Texture("textures/r.png", invert=True)}
    )
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    monkeypatch.setattr(gate.files.tempfile, "tempdir", str(tmp))

    def full(self, _data):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(self))

    monkeypatch.setattr(pathlib.Path, "write_bytes", full)
    out = tmp_path / "out"
    with pytest.raises(UserError) as err:
        write_export([mat], [TextureFile("textures/r.png", data=data)], "gltf", out, "x")
    monkeypatch.undo()
    assert f"in {tmp}: the disk is full" in str(err.value), err.value
    assert not out.exists() and list(tmp.iterdir()) == []


def test_the_cli_refuses_with_one_line_and_force_replaces(tmp_path):
    """``ctlab export`` over a user's .mtlx: exit 2 and one line; --force replaces it."""
    build = (
        "import sys; sys.path.insert(0, sys.argv[1]); import bpy; "
        "from addon import blender; from addon.blender import materials; "
        "bpy.ops.wm.read_factory_settings(use_empty=True); "
        "from addon.core.model import ModelOptions; "
        "m = materials.model_material('Gold', impl='nodes', "
        "options=ModelOptions(ibl='split_sum')); m.use_fake_user = True; "
        "bpy.ops.wm.save_as_mainfile(filepath=sys.argv[2])"
    )
    blend = tmp_path / "f.blend"
    run = subprocess.run([sys.executable, "-c", build, str(ROOT), str(blend)], timeout=300)
    assert run.returncode == 0
    out = tmp_path / "out"
    out.mkdir()
    (out / "Gold.mtlx").write_text("mine")
    args = [*CTLAB, "export", str(blend), "--format", "materialx", "--out", str(out)]
    run = subprocess.run(args, capture_output=True, text=True, timeout=300)
    errors = [line for line in run.stderr.splitlines() if line.strip()]
    assert run.returncode == 2 and len(errors) == 1, run.stderr
    assert "Gold.mtlx is a file ctlab did not write" in errors[0]
    assert (out / "Gold.mtlx").read_text() == "mine"
    run = subprocess.run([*args, "--force"], capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr
    assert "<materialx" in (out / "Gold.mtlx").read_text()


def test_bake_out_keeps_a_users_file_before_baking(tmp_path, monkeypatch, capsys):
    """``bake --out DIR`` where DIR holds the user's irradiance.exr: refused in one line
    before anything is baked (the cache stays empty), the file kept; --force replaces it."""
    from addon.core import ibl_bake
    from addon.jobs import cli

    monkeypatch.setenv("CTLAB_CACHE", str(tmp_path / "cache"))
    hdri = tiny_hdri(tmp_path / "sky.exr")
    out = tmp_path / "out"
    out.mkdir()
    mine = out / ibl_bake.IRRADIANCE_FILE
    mine.write_bytes(b"the user's irradiance")
    assert cli.main(["bake", str(hdri), "--out", str(out)]) == 2
    err = [line for line in capsys.readouterr().err.splitlines() if line.strip()]
    assert len(err) == 1 and "is a file ctlab did not write" in err[0], err
    assert mine.read_bytes() == b"the user's irradiance"
    assert sorted(p.name for p in out.iterdir()) == [mine.name]
    assert not (tmp_path / "cache").exists() or not any((tmp_path / "cache").iterdir())
    assert cli.main(["bake", str(hdri), "--out", str(out), "--force"]) == 0
    assert mine.read_bytes() != b"the user's irradiance"
    assert cli.main(["bake", str(hdri), "--out", str(out)]) == 0  # its own files now
