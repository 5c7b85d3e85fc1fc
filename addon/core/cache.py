"""The cache folder: the bakes, importance tables and DFG tables derived from files and kept
under their content hash. Never the add-on's install folder (it may be read-only).

Order: $CTLAB_CACHE; the folder a higher layer names (``set_folder_resolver``: the add-on's
preferences, or the extension's user folder when running installed); $XDG_CACHE_HOME or
~/.cache, under cook-torrance-lab."""

from __future__ import annotations

import os
from pathlib import Path

from .errors import UserError

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
    return path
