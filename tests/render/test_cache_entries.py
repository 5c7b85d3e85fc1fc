"""The cache under damage (core/cache.py): a damaged entry is found by its manifest and built
again, never used; an entry holding a file ctlab did not write loses nothing of the user's; a
dead process's staging folder is removed; an unwritable cache folder is one line naming the
remedy."""

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from helpers import one_line, tiny_hdri
from addon.core import cache, files, ibl_bake
from addon.core.compare import read_image
from addon.core.errors import UserError
from addon.core.hdri import write_float_exr
from addon.jobs import cli

# The cache's entries: the same on every Blender series, so run on one
# (docs/testing.md, "Which tests run on both series").
pytestmark = pytest.mark.one_series

SMALL = ["--grid", "2x2", "--size", "32", "--samples", "1"]

# The rows of docs/bad-input.md that these tests hold (test_bad_input checks the table lists
# them and that each names a test here): ID -> the test.
CASES = {
    "cache-foreign-file": "test_a_damaged_cache_entry_with_a_users_file_loses_nothing_of_theirs",
    "cache-entry-not-removable": "test_a_damaged_entry_ctlab_may_not_remove_is_one_line",
    "plot-entry-resigned": "test_a_re_signed_damaged_plot_entry_is_rendered_again",
}


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
    line = one_line(
        capsys, cli.main(["bake", str(tiny_hdri(tmp_path / "sky.exr"))]), "cache folder not usable"
    )
    assert "CTLAB_CACHE" in line and "preferences" in line


def _plot_entry(monkeypatch, tmp_path):
    """A plot cache entry of a small result, as plot_cache.cached keeps it."""
    from addon.core.brdf_plot import PlotSettings
    from addon.jobs import plot_cache

    monkeypatch.setenv("CTLAB_CACHE", str(tmp_path / "cache"))
    settings = PlotSettings(views=("D",))
    results = {"main": {"slice": {"f_r": np.ones((2, 3), np.float32)}}, "labels": {"main": "x"}}
    assert plot_cache.cached(settings, lambda: results)["labels"] == {"main": "x"}
    return plot_cache, settings, results, cache.lookup(plot_cache.key(settings))


def test_a_re_signed_damaged_plot_entry_is_rendered_again(tmp_path, monkeypatch):
    """A plot entry whose results were damaged and its manifest signed again (so the
    manifest holds): garbage bytes, or a valid .npz with one array changed. Either is found
    when read, removed and rendered again, never used and never a traceback."""
    plot_cache, settings, results, folder = _plot_entry(monkeypatch, tmp_path)
    data = dict(np.load(folder / plot_cache.RESULTS))
    data["main|slice|f_r"] = np.zeros((2, 3), np.float32)  # a valid file, the wrong numbers
    for damage in (lambda p: p.write_bytes(b"PK\x03\x04 not a zip"), lambda p: np.savez(p, **data)):
        damage(folder / plot_cache.RESULTS)
        (folder / cache.MANIFEST).write_text(json.dumps(cache._manifest(folder)))
        assert cache.intact(folder)  # the manifest holds: only reading finds the damage
        fresh = {"main": {"slice": {"f_r": np.full((2, 3), 2.0, np.float32)}}, "labels": {}}
        got = plot_cache.cached(settings, lambda f=fresh: f)
        assert got is fresh
        again = plot_cache.cached(settings, lambda: pytest.fail("not read from the cache"))
        assert np.array_equal(again["main"]["slice"]["f_r"], fresh["main"]["slice"]["f_r"])


def test_a_damaged_entry_ctlab_may_not_remove_is_one_line(tmp_path, monkeypatch):
    """A damaged entry that ctlab may not remove (another user's: unlink refused) is one
    line naming the entry and the remedy, not a traceback; its files stay."""
    plot_cache, settings, results, folder = _plot_entry(monkeypatch, tmp_path)
    (folder / plot_cache.RESULTS).write_bytes(b"damaged")  # the manifest no longer holds

    def refused(self, *a, **k):
        raise PermissionError(13, "Permission denied", str(self))

    monkeypatch.setattr(Path, "unlink", refused)
    with pytest.raises(UserError) as err:
        plot_cache.cached(settings, lambda: results)
    monkeypatch.undo()
    message = str(err.value)
    assert "\n" not in message
    assert f"the damaged cache entry {folder} cannot be removed (Permission denied" in message
    assert (folder / plot_cache.RESULTS).read_bytes() == b"damaged"
