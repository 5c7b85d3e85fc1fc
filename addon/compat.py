"""The differences between the Blender releases the add-on runs on, in one place.

- ``bpy.utils.expose_bundled_modules`` (4.4+) puts the bundled OpenImageIO and oslquery Python
  bindings of Blender-as-a-module on ``sys.path``; the bpy 4.2 wheel ships neither binding.
- EEVEE's engine identifier is ``BLENDER_EEVEE_NEXT`` from 4.2 to 4.5, ``BLENDER_EEVEE`` from 5.0.
- ``Material.use_nodes`` / ``World.use_nodes`` are deprecated in 5.0 (node trees always exist).
"""

from __future__ import annotations

import bpy

from .errors import UserError


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
        raise UserError(f"this Blender ({bpy.app.version_string}) has no bundled {name} Python "
                        "module, which Cook-Torrance Lab needs; use Blender 4.5 or newer") from None


def eevee_engine_id() -> str:
    return 'BLENDER_EEVEE_NEXT' if bpy.app.version < (5, 0, 0) else 'BLENDER_EEVEE'


def use_nodes(block) -> None:
    """Give a material or world its node tree (implicit from 5.0, where use_nodes is deprecated)."""
    if bpy.app.version < (5, 0, 0) or block.node_tree is None:
        block.use_nodes = True
