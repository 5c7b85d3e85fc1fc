"""What the operators share: the enum items, the progress indicator, the active material,
the implementation the preferences choose."""

from __future__ import annotations

import bpy

from ...core.model import IBL_MODES, SHADERS
from ...core.settings import MatrixSettings
from .. import preferences
from ..labels import IBL_LABELS, SHADER_LABELS

_DEFAULTS = MatrixSettings()
_IBL_ITEMS = tuple((m, *IBL_LABELS[m]) for m in IBL_MODES)
_SHADER_ITEMS = tuple((s, *SHADER_LABELS[s]) for s in SHADERS)
_IMPL_ITEMS = (
    ("PREFERENCES", "Preferences' Default", "The add-on preferences' implementation"),
) + preferences.IMPLEMENTATION_ITEMS
_SCOPE_ITEMS = (
    ("ACTIVE", "Active Material", "The active object's active material"),
    ("SELECTED", "Selected Objects", "Every material of the selected objects"),
)


class _progress:
    """The window manager's progress indicator (a no-op without a window), as a
    ``progress(fraction, message)`` callable."""

    def __init__(self, context, status: str = ""):
        self.wm = context.window_manager if context.window else None
        self.workspace = getattr(context, "workspace", None) if context.window else None
        self.status = status

    def __enter__(self):
        if self.wm is not None:
            self.wm.progress_begin(0, 100)
        if self.status:
            print(f"Cook-Torrance Lab: {self.status}", flush=True)
            if self.workspace is not None:
                self.workspace.status_text_set(self.status)
                try:  # drawn now, before the work blocks
                    bpy.ops.wm.redraw_timer(type='DRAW_WIN_SWAP', iterations=1)
                except RuntimeError:  # no window to draw (background)
                    pass
        return self

    def __call__(self, fraction, message):
        if self.wm is not None:
            self.wm.progress_update(int(100 * fraction))

    def __exit__(self, *exc):
        if self.wm is not None:
            self.wm.progress_end()
        if self.status and self.workspace is not None:
            self.workspace.status_text_set(None)


def _implementation(choice: str) -> str:
    return preferences.get().implementation if choice == "PREFERENCES" else choice


def _active_material(context):
    mat = getattr(context, "material", None)
    if mat is None and context.object is not None:
        mat = context.object.active_material
    return mat


def _default_hdri() -> str:
    return bpy.path.abspath(preferences.get().hdri) if preferences.get().hdri else ""
