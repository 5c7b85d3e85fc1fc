"""The cache folder: the bakes, importance tables and DFG tables derived from files and kept
under their content hash. Never the add-on's install folder (it may be read-only). Each entry
is a folder written whole with a manifest of its files' sizes and content hashes, checked
every time the entry is used: a damaged entry is built again, never used.

Order: $CTLAB_CACHE; the folder a higher layer names (``set_folder_resolver``: the add-on's
preferences, or the extension's user folder when running installed); $XDG_CACHE_HOME or
~/.cache, under cook-torrance-lab."""

from __future__ import annotations

import hashlib
import json
import os
import shutil
from pathlib import Path

from .errors import UserError
from .files import atomic_folder, remove_stale_temporaries

_resolver = None


def set_folder_resolver(resolver) -> None:
    """``resolver(create) -> str | None`` names the cache folder when $CTLAB_CACHE is unset
    (the Blender layer installs one; None falls back to the XDG folder)."""
    global _resolver
    _resolver = resolver


def cache_dir(create: bool = True) -> Path:
    """The cache folder, created unless ``create`` is False (a lookup that must not leave an
    empty folder behind)."""
    named = os.environ.get("CTLAB_CACHE") or (_resolver(create) if _resolver else None)
    if named:
        path = Path(named)
    else:
        base = os.environ.get("XDG_CACHE_HOME") or os.path.join(Path.home(), ".cache")
        path = Path(base) / "cook-torrance-lab"
    if create:
        try:
            path.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise UserError(f"cache folder not usable: {path} ({exc.strerror or exc}); choose "
                            "another in the add-on's preferences or set CTLAB_CACHE") from None
        remove_stale_temporaries(path)          # left by a killed bake, say
    return path


# ----------------------------------------------------------------------------------------
# Cached folders: written whole, each file's size and content hash recorded, checked on use

MANIFEST = "manifest.json"


def _digest(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def _manifest(folder: Path) -> dict:
    return {p.name: {"bytes": p.stat().st_size, "sha256": _digest(p)}
            for p in sorted(Path(folder).iterdir()) if p.is_file() and p.name != MANIFEST}


def intact(folder: Path) -> bool:
    """Whether a cached folder holds exactly the files its manifest lists, each of the
    recorded size and content."""
    try:
        listed = json.loads((Path(folder) / MANIFEST).read_text())
        return isinstance(listed, dict) and bool(listed) and listed == _manifest(folder)
    except (OSError, ValueError):
        return False


def lookup(key: str) -> Path | None:
    """The cached folder ``key`` when it is intact, else None; a damaged one (a file
    truncated, changed or missing) is removed so that it is built again."""
    folder = cache_dir(create=False) / key
    if not folder.is_dir():
        return None
    if intact(folder):
        return folder
    shutil.rmtree(folder, ignore_errors=True)
    return None


def build(key: str, fill) -> Path:
    """Build the cached folder ``key`` with fill(staging), sign it with its manifest, and
    put it in place whole (core.files.atomic_folder)."""
    def fill_and_sign(staging: Path) -> None:
        fill(staging)
        (staging / MANIFEST).write_text(json.dumps(_manifest(staging), indent=2))
    folder = cache_dir() / key
    atomic_folder(folder, fill_and_sign)
    return folder


def cached(key: str, fill) -> Path:
    """The intact cached folder ``key``, built by fill(staging) when missing or damaged."""
    return lookup(key) or build(key, fill)
