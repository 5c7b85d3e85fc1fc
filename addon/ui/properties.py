"""Properties the add-on adds to Blender's data, registered and removed together.

- ``Material.ctlab_view``, ``ctlab_g_model``, ``ctlab_diffuse_model``, ``ctlab_units``,
  ``ctlab_ibl``, ``ctlab_light_transport``: dropdowns that read and write the material's
  Cook-Torrance node itself (get/set functions), so they can never disagree with it; unusable
  on materials without the model.
- ``Scene.ctlab_sun``: the Sun the model's key light follows (empty: the scene's first Sun);
  ``ctlab_residual_pass``: the residual albedo pass, read and written through light_sync.
- ``WindowManager.ctlab_job_*``: the background comparison's progress, for the sidebar;
  ``ctlab_plot_*``: the BRDF plot's, for the material panel.
"""

from __future__ import annotations

import bpy
from bpy.props import BoolProperty, EnumProperty, FloatProperty, PointerProperty, StringProperty

from ..blender import model_node
from ..core.model import OPTION_VALUES
from .labels import IBL_LABELS, LIGHT_TRANSPORT_LABELS, label


def _items(key):
    return tuple((v, label(v), "") for v in OPTION_VALUES[key])


# EnumProperty items must be module-level (the annotations below are evaluated lazily).
VIEW_ITEMS = _items("view")
G_ITEMS = _items("g_model")
DIFFUSE_ITEMS = _items("diffuse_model")
UNITS_ITEMS = _items("units")
ENERGY_ITEMS = tuple(
    (v, label(v), d)
    for v, d in zip(
        OPTION_VALUES["energy"],
        ("The seed's model: single-scattering specular", "Kulla-Conty multiple scattering"),
        strict=True,
    )
)
IBL_ITEMS = tuple((m, *IBL_LABELS[m]) for m in OPTION_VALUES["ibl"])
TRANSPORT_ITEMS = tuple((m, *LIGHT_TRANSPORT_LABELS[m]) for m in OPTION_VALUES["light_transport"])


def _option_property(key: str, name: str, items, description: str):
    values = OPTION_VALUES[key]

    def get(mat):
        node = model_node.find(mat)
        return values.index(model_node.get_option(node, key)) if node is not None else 0

    def set_(mat, index):
        from ..core.errors import UserError

        node = model_node.find(mat)
        if node is None:
            return
        try:
            model_node.set_option(node, key, values[index])
            if key in ("ibl", "light_transport"):
                from ..blender import light_sync

                light_sync.update_environment(node, bpy.context.scene)
                light_sync.update_residual(mat.node_tree, node, bpy.context.scene)
        except UserError as exc:  # a setter cannot report: the console, and no change
            print(f"Cook-Torrance Lab: {exc}")

    return EnumProperty(name=name, items=items, get=get, set=set_, description=description)


def _sun_poll(self, obj):
    return obj.type == 'LIGHT' and obj.data.type == 'SUN'


def _sun_changed(scene, context):
    from ..blender import light_sync

    for mat, _ in light_sync.user_materials():
        light_sync.sync_material(mat, scene, environment=False)


def _get_residual_pass(scene):
    from ..blender import light_sync

    return light_sync.residual_pass(scene)


def _set_residual_pass(scene, on):
    from ..blender import light_sync

    light_sync.set_residual_pass(scene, on)


def register() -> None:
    M = bpy.types.Material
    M.ctlab_view = _option_property(
        "view", "View", VIEW_ITEMS, "What the material shows: the lit result or one term alone"
    )
    M.ctlab_g_model = _option_property(
        "g_model", "Geometry (G)", G_ITEMS, "The geometry / shadowing-masking term"
    )
    M.ctlab_diffuse_model = _option_property(
        "diffuse_model", "Diffuse", DIFFUSE_ITEMS, "The diffuse term"
    )
    M.ctlab_units = _option_property(
        "units", "Units", UNITS_ITEMS, "Physical, or Unity's (x pi on direct light)"
    )
    M.ctlab_energy = _option_property(
        "energy",
        "Energy",
        ENERGY_ITEMS,
        "Compensate the energy single scattering loses (Kulla and Conty 2017)",
    )
    M.ctlab_ibl = _option_property(
        "ibl", "Indirect Light", IBL_ITEMS, "How the HDRI lights the surface"
    )
    M.ctlab_light_transport = _option_property(
        "light_transport",
        "Light Transport",
        TRANSPORT_ITEMS,
        "Lab: the model lights itself, exactly, and sees no other object; Scene: Cycles path "
        "traces it with everything in the scene",
    )
    bpy.types.Scene.ctlab_sun = PointerProperty(
        name="Key Sun",
        type=bpy.types.Object,
        poll=_sun_poll,
        update=_sun_changed,
        description="The Sun the Cook-Torrance key light follows; empty: the scene's first Sun",
    )
    bpy.types.Scene.ctlab_residual_pass = BoolProperty(
        name="Residual Albedo Pass",
        get=_get_residual_pass,
        set=_set_residual_pass,
        description="The scene transport's residual albedo as the render pass residual_albedo "
        "(Shader AOV); off by default, as it costs every camera hit the correction's inputs",
    )
    W = bpy.types.WindowManager
    W.ctlab_job_progress = FloatProperty(name="Progress", subtype='FACTOR', min=0, max=1)
    W.ctlab_job_message = StringProperty(name="Comparison")
    W.ctlab_job_state = StringProperty(name="State")
    W.ctlab_plot_message = StringProperty(name="BRDF Plot")
    W.ctlab_plot_state = StringProperty(name="BRDF Plot State")


NAMES = (
    (
        bpy.types.Material,
        (
            "ctlab_view",
            "ctlab_g_model",
            "ctlab_diffuse_model",
            "ctlab_units",
            "ctlab_energy",
            "ctlab_ibl",
            "ctlab_light_transport",
        ),
    ),
    (bpy.types.Scene, ("ctlab_sun", "ctlab_residual_pass")),
    (
        bpy.types.WindowManager,
        (
            "ctlab_job_progress",
            "ctlab_job_message",
            "ctlab_job_state",
            "ctlab_plot_message",
            "ctlab_plot_state",
        ),
    ),
)


def unregister() -> None:
    for owner, names in NAMES:
        for name in names:
            if hasattr(owner, name):
                delattr(owner, name)
