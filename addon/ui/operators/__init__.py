"""The add-on's operators. Each validates before it changes anything, reports a UserError as
an ERROR (headless: bpy.ops raises RuntimeError with the message) and changes only what its
description says; the ones that edit a user's data are undoable."""

from .common import _SHADER_ITEMS
from .comparison import (
    CTLAB_OT_cancel_comparison,
    CTLAB_OT_render_comparison,
    CTLAB_OT_scene_comparison,
)
from .export import CTLAB_OT_export_materialx, CTLAB_OT_export_unity
from .jobs import JOBS, PLOT_IMAGE, _job_tick, show_plot, stop_jobs
from .lighting import CTLAB_OT_sync_lighting, sync_summary
from .materials import (
    CTLAB_OT_add_node_group,
    CTLAB_OT_add_texture,
    CTLAB_OT_convert_to_cook_torrance,
    CTLAB_OT_convert_to_principled,
    CTLAB_OT_new_material,
    CTLAB_OT_set_view_all,
    CTLAB_OT_switch_implementation,
)
from .matrix import CTLAB_OT_bake_environment, CTLAB_OT_build_sphere_matrix
from .plot import CTLAB_OT_brdf_plot, plot_command
from .unity_import import CTLAB_OT_import_unity, draw_import_menu

__all__ = [
    "CLASSES",
    "JOBS",
    "PLOT_IMAGE",
    "_SHADER_ITEMS",
    "_job_tick",
    "draw_import_menu",
    "plot_command",
    "show_plot",
    "stop_jobs",
    "sync_summary",
]

CLASSES = (
    CTLAB_OT_build_sphere_matrix,
    CTLAB_OT_bake_environment,
    CTLAB_OT_new_material,
    CTLAB_OT_add_node_group,
    CTLAB_OT_add_texture,
    CTLAB_OT_switch_implementation,
    CTLAB_OT_convert_to_cook_torrance,
    CTLAB_OT_convert_to_principled,
    CTLAB_OT_set_view_all,
    CTLAB_OT_sync_lighting,
    CTLAB_OT_render_comparison,
    CTLAB_OT_scene_comparison,
    CTLAB_OT_cancel_comparison,
    CTLAB_OT_brdf_plot,
    CTLAB_OT_export_materialx,
    CTLAB_OT_export_unity,
    CTLAB_OT_import_unity,
)
