"""Paths that only Blender knows: its bundled HDRIs, the add-on's preferences' cache folder
and the installed extension's user folder (installed as the core's cache resolver)."""

from __future__ import annotations

from pathlib import Path

import bpy

from ..core import cache

# The package that names the add-on's preferences: this module is <package>.addon.blender.paths
# when Blender loads the extension (bl_ext.<repo>.cook_torrance_lab) or the background job its
# private copy; a checkout imported from its root has only addon.blender, and uses "addon".
PACKAGE = (
    __package__.rsplit(".", 2)[0] if __package__.count(".") >= 2 else __package__.split(".")[0]
)
BUNDLED_HDRIS = ("city", "courtyard", "forest", "interior", "night", "studio", "sunrise", "sunset")


def bundled_hdri(name: str = "forest") -> Path:
    """One of Blender's bundled CC0 HDRIs (studiolights/world/<name>.exr)."""
    return Path(bpy.utils.system_resource('DATAFILES', path="studiolights/world")) / f"{name}.exr"


def resolve_hdri(hdri: str) -> Path:
    """A settings' HDRI: its file, or Blender's bundled forest.exr when empty."""
    return Path(hdri) if hdri else bundled_hdri("forest")


def preferences():
    """The add-on's preferences, or None when it is not enabled under its package name."""
    try:
        addon = bpy.context.preferences.addons.get(PACKAGE)
    except AttributeError:
        return None
    return addon.preferences if addon is not None else None


def _cache_folder(create: bool) -> str | None:
    prefs = preferences()
    if prefs is not None and getattr(prefs, "cache_folder", ""):
        return bpy.path.abspath(prefs.cache_folder)
    if PACKAGE.startswith("bl_ext."):
        return bpy.utils.extension_path_user(PACKAGE, path="cache", create=create)
    return None


cache.set_folder_resolver(_cache_folder)
