"""The cache folder: the bakes, importance tables and DFG tables derived from files and kept
under their content hash. Never the add-on's install folder (it may be read-only). Each entry
is a folder written whole with a manifest of its files' sizes and content hashes, checked
every time the entry is used: a damaged entry is built again, never used.

Order: $CTLAB_CACHE; the folder a higher layer names (``set_folder_resolver``: the add-on's
preferences, or the extension's user folder when running installed); $XDG_CACHE_HOME or
~/.cache, under cook-torrance-lab. The folder passes the path gate (core.paths) and must be
writable: one that exists but is not (another user's, a read-only mount) is refused with the
remedy, $CTLAB_CACHE or the add-on's preference.

Ownership: ctlab removes only what it wrote. A damaged entry loses the files its manifest
lists (and the manifest); a folder under a cache key without a manifest of ours, or holding
files the manifest does not list, is left alone with the reason in the error."""

from __future__ import annotations

import json
import os
from pathlib import Path

from .errors import UserError
from . import files
from .files import atomic_folder, probe_writable, remove_stale_temporaries
from .paths import clean

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
    path = clean(str(path), "cache folder", output=True)
    if create:
        try:
            path.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise _unusable(path, exc.strerror or str(exc)) from None
        why = probe_writable(path)
        if why:
            raise _unusable(path, f"not writable: {why}")
        remove_stale_temporaries(path)  # left by a killed bake, say
    return path


files.cache_locator = lambda: cache_dir(create=False)


def _unusable(path: Path, why: str) -> UserError:
    return UserError(
        f"cache folder not usable: {path} ({why}); choose another in the "
        "add-on's preferences or set CTLAB_CACHE"
    )


# ----------------------------------------------------------------------------------------
# Cached folders: written whole, each file's size and content hash recorded, checked on use

MANIFEST = "manifest.json"


def _manifest(folder: Path) -> dict:
    return {
        p.name: {"bytes": p.stat().st_size, "sha256": files.sha256(p)}
        for p in sorted(Path(folder).iterdir())
        if p.is_file() and p.name != MANIFEST
    }


def _listed(folder: Path) -> dict | None:
    """The manifest of a cached folder when it is one of ours (name -> bytes and sha256 of
    plain file names), else None."""
    try:
        listed = json.loads((Path(folder) / MANIFEST).read_text())
    except (OSError, ValueError):
        return None
    ok = (
        isinstance(listed, dict)
        and bool(listed)
        and all(
            isinstance(k, str)
            and k == Path(k).name
            and k not in (".", "..", MANIFEST)
            and isinstance(v, dict)
            and set(v) == {"bytes", "sha256"}
            for k, v in listed.items()
        )
    )
    return listed if ok else None


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
    _remove_damaged(folder)
    return None


def _remove_damaged(folder: Path) -> None:
    """Remove a damaged entry: only the files its manifest lists, then the manifest and the
    folder. Anything else there (a folder, a file it does not list: not ctlab's) stays, and
    the entry is refused with the reason; so is one ctlab may not remove (another user's)."""
    try:
        _remove_listed(folder)
    except OSError as exc:
        raise UserError(
            f"the damaged cache entry {folder} cannot be removed "
            f"({exc.strerror or exc}: {exc.filename or folder}); it was left alone: remove "
            "it yourself or choose another cache folder (CTLAB_CACHE, the add-on's "
            "preferences)"
        ) from None


def _remove_listed(folder: Path) -> None:
    listed = _listed(folder)
    if listed is None:
        raise UserError(
            f"{folder} in the cache is not a cache entry ctlab wrote (no "
            "manifest of its files); it was left alone: move it away or choose "
            "another cache folder (CTLAB_CACHE, the add-on's preferences)"
        )
    others = sorted(p.name for p in folder.iterdir() if p.name not in listed and p.name != MANIFEST)
    if others:
        raise UserError(
            f"the cache entry {folder} holds {others[0]}, which ctlab did not "
            "write; it was left alone: move it away or choose another cache "
            "folder (CTLAB_CACHE, the add-on's preferences)"
        )
    for name in listed:
        p = folder / name
        if p.is_file() and not p.is_symlink():
            p.unlink()
        elif p.exists() or p.is_symlink():
            raise UserError(
                f"the cache entry {folder} holds {name}, which is not a file "
                "ctlab wrote; it was left alone: move it away"
            )
    (folder / MANIFEST).unlink(missing_ok=True)
    folder.rmdir()


def discard(folder: Path) -> None:
    """Remove an entry whose files match its manifest but do not read back (re-signed by
    hand, say): as a damaged one (``_remove_damaged``)."""
    _remove_damaged(Path(folder))


def build(key: str, fill) -> Path:
    """Build the cached folder ``key`` with fill(staging), sign it with its manifest, and
    put it in place whole (core.files.atomic_folder)."""

    def fill_and_sign(staging: Path) -> None:
        fill(staging)
        (staging / MANIFEST).write_text(json.dumps(_manifest(staging), indent=2))

    folder = cache_dir() / key
    if folder.exists() and not intact(folder):
        _remove_damaged(folder)
    atomic_folder(folder, fill_and_sign)
    return folder


def cached(key: str, fill) -> Path:
    """The intact cached folder ``key``, built by fill(staging) when missing or damaged."""
    return lookup(key) or build(key, fill)
