"""The differences between the Blender releases the add-on runs on, in one place.

- ``bpy.utils.expose_bundled_modules`` (4.4+) puts the bundled OpenImageIO and oslquery Python
  bindings of Blender-as-a-module on ``sys.path``; the bpy 4.2 wheel ships neither binding.
- EEVEE's engine identifier is ``BLENDER_EEVEE_NEXT`` from 4.2 to 4.5, ``BLENDER_EEVEE`` from 5.0.
- ``Material.use_nodes`` / ``World.use_nodes`` are deprecated in 5.0 (node trees always exist).
- OSL's ``texture()`` of a file: up to 5.1 OpenImageIO's texture system serves it (t = 0 is the
  file's top row; "interp" and "swrap" options apply); from 5.2 Cycles' image manager does
  (t = 0 is the bottom row; always bilinear, edges clamped). The shader is told which
  (``osl_texture_rows_bottom_up``) and reads tables only at texel centres, so both give the
  same values. ``gettextureinfo()`` crashes Cycles 5.2 (a segmentation fault while it optimises
  the shader), so the shader never calls it. tests/render/test_versions.py measures both facts.
"""

from __future__ import annotations

import bpy

from ..core.errors import UserError


def expose_bundled_modules() -> None:
    expose = getattr(bpy.utils, "expose_bundled_modules", None)
    if expose is not None:
        expose()


def bundled_module(name: str):
    """Import one of Blender's bundled Python bindings (OpenImageIO, oslquery)."""
    import importlib

    try:
        return importlib.import_module(name)
    except ImportError:
        expose_bundled_modules()
    try:
        return importlib.import_module(name)
    except ImportError:
        raise UserError(
            f"this Blender ({bpy.app.version_string}) has no bundled {name} Python "
            "module, which Cook-Torrance Lab needs; use Blender 4.5 or newer"
        ) from None


def eevee_engine_id() -> str:
    return 'BLENDER_EEVEE_NEXT' if bpy.app.version < (5, 0, 0) else 'BLENDER_EEVEE'


def use_nodes(block) -> None:
    """Give a material or world its node tree (implicit from 5.0, where use_nodes is deprecated)."""
    if bpy.app.version < (5, 0, 0) or block.node_tree is None:
        block.use_nodes = True


def osl_texture_rows_bottom_up() -> bool:
    """Whether OSL's texture() counts t from the file's bottom row (Blender 5.2 and later)."""
    return bpy.app.version >= (5, 2, 0)
