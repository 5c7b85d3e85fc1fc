"""Cook-Torrance Lab: a Blender extension (the repository root is the extension source)."""

from .addon.register import register, unregister  # noqa: F401
