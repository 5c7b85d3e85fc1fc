"""The write gate (addon/core/gate.py) over any names, without Blender: every name a user's
data can give a file (any Unicode, control characters, undecodable bytes, up to and past 255
bytes, names that differ only by case) either lands as exactly that file inside the folder or
is refused as a UserError; never another exception, never a file outside the folder, never a
file replaced that the record does not hold."""

import os
import string
import tempfile
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

from addon.core import gate
from addon.core.errors import UserError

NAMES = st.one_of(
    st.text(min_size=1, max_size=90),
    st.text(alphabet=string.printable + "\x00\x1b\u00e9\u4e2d\U0001f600/\\.", max_size=300),
    st.binary(min_size=1, max_size=260).map(os.fsdecode),  # a non-UTF-8 file name's text
    st.sampled_from(
        [
            "..",
            ".",
            "a" * 255,
            "a" * 256,
            "\u00e9" * 128,
            "CON",
            ".ctlab-written",
            ".ctlab-written.json",
        ]
    ),
)


def _everything(folder: Path) -> set:
    return {p.relative_to(folder).as_posix() for p in folder.rglob("*")}


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(names=st.lists(NAMES, min_size=1, max_size=4))
def test_any_names_land_whole_or_are_refused(names):
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp) / "out"
        writers = {}
        for i, name in enumerate(names):
            writers[f"textures/{name}" if i % 2 else name] = lambda path, i=i: path.write_bytes(
                b"%d" % i
            )
        try:
            written = gate.Gate(root, "files").write(writers)
        except (UserError, ValueError):
            # refused before any byte: nothing at all was made (not even the folder)
            assert not root.exists()
            return
        assert len(written) == len(writers)
        for rel, path in zip(writers, written):
            assert path.is_file() and root in path.parents
            assert path.relative_to(root).as_posix() == rel
            assert all(len(os.fsencode(part)) <= 255 for part in Path(rel).parts)
        folders = {p.as_posix() for r in writers for p in Path(r).parents if str(p) != "."}
        assert _everything(root) == set(writers) | folders | {gate.RECORD}
        assert not any(".partial" in p for p in _everything(Path(tmp)))
        # a second write of the same names replaces ctlab's own files
        gate.Gate(root, "files").write(writers)


@pytest.mark.parametrize(
    "name", ["a" * 224, "..", ".", "a/b", "x\0y", os.fsdecode(b"\xff\xfe.png"), ""]
)
def test_names_the_file_system_cannot_take_are_one_line(name):
    with pytest.raises(UserError) as err:
        gate.check_name(name, "the texture name")
    assert "\n" not in str(err.value) and "the texture name" in str(err.value)


def test_names_differing_by_case_are_refused_as_one_file(tmp_path):
    """Two outputs whose names a case-folding file system (macOS, Windows) cannot tell apart,
    Gold.mtlx and gold.mtlx, are one output twice: refused, nothing written."""
    with pytest.raises(UserError, match="two outputs would share"):
        gate.Gate(tmp_path / "out", "files").check(["Gold.mtlx", "gold.mtlx"])
    assert not (tmp_path / "out").exists()


def test_a_name_leaves_room_for_its_staged_file(tmp_path):
    """The longest name taken is staged and renamed in place (its staging name is longer)."""
    name = "a" * (gate.MAX_OUTPUT_NAME_BYTES - 4) + ".bin"
    gate.Gate(tmp_path, "files").write({name: lambda p: p.write_bytes(b"x")})
    assert (tmp_path / name).read_bytes() == b"x"
    with pytest.raises(UserError, match="not a valid file name"):
        gate.Gate(tmp_path, "files").check(["a" + name])
