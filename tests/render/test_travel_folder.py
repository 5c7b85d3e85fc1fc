"""The travel folder beside a saved .blend, ``<name>_ctlab/`` (blender/travel.py), goes through
the write gate (core/gate.py): a user's file of a name the save writes is never replaced, a
link there is never written through, files ctlab copied on an earlier save are replaced
when their source changed, and a Save As after reopening a saved file carries the files to
the new place (the ``//`` inputs resolve from the file as it was saved)."""

import os
import shutil

import bpy
import pytest

from addon.blender import compat, model_node, osl_shader, travel
from addon.core import gate
from addon.core.errors import UserError

CASES = {
    "travel-users-file": "test_a_users_file_in_the_travel_folder_is_never_replaced",
    "travel-folder-link": "test_a_link_in_the_travel_folder_is_never_written_through",
}


@pytest.fixture
def entry(tmp_path):
    """A cache entry of two tables (as core.cache writes them, with a manifest)."""
    folder = tmp_path / "cache" / "dfg-0123"
    folder.mkdir(parents=True)
    (folder / "a.bin").write_bytes(b"table a")
    (folder / "b.bin").write_bytes(b"table b")
    (folder / "manifest.json").write_text("{}")
    return folder


def test_a_users_file_in_the_travel_folder_is_never_replaced(tmp_path, entry):
    """The user's own file where the save copies a table: refused in one line, kept byte for
    byte, and nothing else of the entry copied; a file of the same bytes is kept without a
    write; once the user's file is gone, a second carry copies the table, and a third, after
    the table changed, replaces ctlab's own copy."""
    folder = tmp_path / "shot_ctlab"
    (folder / entry.name).mkdir(parents=True)
    mine = folder / entry.name / "a.bin"
    mine.write_bytes(b"the user's own a.bin")
    with pytest.raises(UserError, match="a.bin is a file ctlab did not write"):
        travel._carry(entry, folder)
    assert mine.read_bytes() == b"the user's own a.bin"
    assert sorted(p.name for p in (folder / entry.name).iterdir()) == ["a.bin"]
    mine.write_bytes(b"table a")  # the same bytes as the table: kept, not rewritten
    stamp = mine.stat().st_mtime_ns
    travel._carry(entry, folder)
    assert mine.stat().st_mtime_ns == stamp
    assert (folder / entry.name / "b.bin").read_bytes() == b"table b"
    (entry / "b.bin").write_bytes(b"table b, rebuilt")
    travel._carry(entry, folder)  # ctlab's own copy: replaced
    assert (folder / entry.name / "b.bin").read_bytes() == b"table b, rebuilt"
    assert (folder / gate.RECORD).is_file()


def test_a_link_in_the_travel_folder_is_never_written_through(tmp_path, entry):
    """``shot_ctlab/<entry>`` a link to the user's folder: refused, the folder untouched."""
    library = tmp_path / "library"
    library.mkdir()
    folder = tmp_path / "shot_ctlab"
    folder.mkdir()
    (folder / entry.name).symlink_to(library)
    with pytest.raises(UserError, match="is a link where ctlab keeps"):
        travel._carry(entry, folder)
    assert list(library.iterdir()) == []


def _osl_values(mat):
    node = model_node.find(mat)
    return {k: osl_shader.socket(node, k).default_value for k in travel.FILE_INPUTS}


def test_save_as_after_reopening_carries_the_files_to_the_new_place(addon, tmp_path):
    """Save shot.blend, reopen it (its OSL inputs are ``//shot_ctlab/...`` now, the user's
    HDRI beside it ``//sky.exr``), Save As into another folder: every input of the new file
    resolves from there, the add-on's files in ``other_ctlab`` (also after the first
    ``shot_ctlab`` is gone), the user's HDRI by its absolute path."""
    scene = bpy.context.scene
    scene.render.engine = 'CYCLES'
    obj = bpy.data.objects["Cube"]
    mat = bpy.data.materials.new("Paint")
    compat.use_nodes(mat)
    obj.material_slots[0].material = mat
    bpy.context.view_layer.objects.active = obj
    assert bpy.ops.ctlab.convert_to_cook_torrance(implementation="osl") == {'FINISHED'}
    first, second = tmp_path / "first", tmp_path / "second"
    first.mkdir()
    shutil.copyfile(
        osl_shader.socket(model_node.find(mat), "hdri").default_value, first / "sky.exr"
    )
    osl_shader.socket(model_node.find(mat), "hdri").default_value = str(first / "sky.exr")
    bpy.ops.wm.save_as_mainfile(filepath=str(first / "shot.blend"))
    bpy.ops.wm.open_mainfile(filepath=str(first / "shot.blend"), load_ui=False)
    reopened = _osl_values(bpy.data.materials["Paint"])
    assert any(v.startswith("//shot_ctlab") for v in reopened.values()), reopened
    assert reopened["hdri"] == "//sky.exr"  # the user's HDRI beside the file
    bpy.ops.wm.save_as_mainfile(filepath=str(second / "other.blend"))
    shutil.rmtree(first / "shot_ctlab")
    bpy.ops.wm.open_mainfile(filepath=str(second / "other.blend"), load_ui=False)
    saved = _osl_values(bpy.data.materials["Paint"])
    for key, value in saved.items():
        if not value:
            continue
        assert os.path.exists(bpy.path.abspath(value)), (key, value)
        if key == "hdri":  # the user's file stays where it is, now by its absolute path
            assert value == str(first / "sky.exr"), value
        else:
            assert value.startswith("//other_ctlab"), (key, value)
