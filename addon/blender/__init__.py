"""The model in Blender. Importing this layer exposes Blender's bundled Python modules
(OpenImageIO and oslquery, which the core and Cycles' script nodes need) and names the cache
folder from the add-on's preferences or the extension's user folder (blender/paths.py)."""

from . import compat, paths  # noqa: F401

compat.expose_bundled_modules()
