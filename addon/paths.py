"""Where the add-on's own files are read from, and where it may write."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

PACKAGE_ROOT = Path(__file__).resolve().parent.parent     # the extension / repository root
OSL_DIR = PACKAGE_ROOT / "osl"


def cache_dir(create: bool = True) -> Path:
    """A writable cache folder (never the add-on's install folder, which may be read-only).

    Order: $CTLAB_CACHE; the preferences' cache folder; the extension's user folder when
    running as an installed extension; $XDG_CACHE_HOME/cook-torrance-lab;
    ~/.cache/cook-torrance-lab. With ``create`` False the folder is only named (a lookup
    that must not leave an empty folder behind).
    """
    from . import preferences
    env = os.environ.get("CTLAB_CACHE") or preferences.get().cache_folder
    if env:
        import bpy
        path = Path(bpy.path.abspath(env))
    else:
        path = None
        package = __package__.rpartition(".")[0] if __package__ else ""
        if package.startswith("bl_ext."):
            import bpy
            path = Path(bpy.utils.extension_path_user(package, path="cache", create=create))
        if path is None:
            base = os.environ.get("XDG_CACHE_HOME") or os.path.join(Path.home(), ".cache")
            path = Path(base) / "cook-torrance-lab"
    if not create:
        return path
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        from .errors import UserError
        raise UserError(f"cache folder not usable: {path} ({exc.strerror or exc}); choose "
                        "another in the add-on's preferences or set CTLAB_CACHE") from None
    return path


def atomic_folder(final: Path, fill) -> None:
    """Run fill(staging) and rename the staging folder to ``final``: whole or not at all.
    A failed or interrupted fill leaves nothing behind."""
    staging = final.with_name(f".{final.name}.partial-{os.getpid()}")
    shutil.rmtree(staging, ignore_errors=True)
    staging.mkdir(parents=True)
    try:
        fill(staging)
        try:
            staging.rename(final)
        except OSError:
            if not final.is_dir():            # another process finished first: keep theirs
                raise
    finally:
        shutil.rmtree(staging, ignore_errors=True)


def bundled_hdri(name: str = "forest") -> Path:
    """One of Blender's bundled CC0 HDRIs (studiolights/world/<name>.exr)."""
    import bpy
    return Path(bpy.utils.system_resource('DATAFILES', path="studiolights/world")) / f"{name}.exr"
