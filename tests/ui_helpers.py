"""What the add-on's interface tests share (tests/render/test_ui_*.py): a layout that checks
every call against Blender's RNA (``StubLayout``, ``draw``: a real UILayout needs a window),
what registration can leave behind (``registered_state``), a key Sun (``add_sun``) and the
drivers evaluated (``evaluate_drivers``)."""

import types

import bpy

from addon.ui import operators


# ----------------------------------------------------------------------------------------
# A layout that checks every call against Blender's RNA (a real UILayout needs a window)

ICONS = set(bpy.types.UILayout.bl_rna.functions["label"].parameters["icon"].enum_items.keys())


def operator_rna(idname):
    module, name = idname.split(".")
    return getattr(getattr(bpy.ops, module), name).get_rna_type()  # raises when unknown


class OperatorProps:
    def __init__(self, idname):
        object.__setattr__(self, "_rna", operator_rna(idname))

    def __setattr__(self, name, value):
        prop = self._rna.properties.get(name)
        assert prop is not None, f"operator has no property {name!r}"
        if prop.type == 'ENUM':
            assert value in prop.enum_items.keys(), (
                f"{name}={value!r} not in {prop.enum_items.keys()}"
            )


class StubLayout:
    def __init__(self):
        self.calls = []

    def _icon(self, kw):
        assert kw.get("icon", 'NONE') in ICONS, kw.get("icon")

    def row(self, **kw):
        return self

    column = box = split = row

    def separator(self, **kw):
        pass

    def label(self, text="", **kw):
        assert isinstance(text, str)
        self._icon(kw)
        self.calls.append(("label", text))

    def prop(self, data, name, **kw):
        assert name in data.bl_rna.properties, f"{type(data).__name__} has no {name!r}"
        getattr(data, name)  # runs get functions
        self._icon(kw)
        self.calls.append(("prop", name))

    def operator(self, idname, **kw):
        self._icon(kw)
        self.calls.append(("operator", idname))
        return OperatorProps(idname)

    def operator_menu_enum(self, idname, prop, **kw):
        assert operator_rna(idname).properties[prop].type == 'ENUM'
        self._icon(kw)
        self.calls.append(("operator", idname))

    def template_ID(self, data, name, **kw):
        assert name in data.bl_rna.properties
        self.calls.append(("template_ID", name))

    def progress(self, factor=0.0, type='BAR', text=""):
        assert 0.0 <= factor <= 1.0 and isinstance(text, str)
        self.calls.append(("progress", text))


def draw(panel_or_menu, **context):
    ctx = types.SimpleNamespace(
        scene=bpy.context.scene,
        window_manager=bpy.context.window_manager,
        object=None,
        material=None,
        space_data=types.SimpleNamespace(tree_type="ShaderNodeTree"),
    )
    for key, value in context.items():
        setattr(ctx, key, value)
    layout = StubLayout()
    if isinstance(panel_or_menu, type):
        panel_or_menu.draw(types.SimpleNamespace(layout=layout), ctx)
    else:
        panel_or_menu(types.SimpleNamespace(layout=layout), ctx)
    return layout.calls


def registered_state():
    """What registration can leave behind: classes, properties, menu entries, handlers,
    timers, drivers."""
    drivers = sum(
        len(b.node_tree.animation_data.drivers)
        for b in list(bpy.data.materials) + list(bpy.data.worlds)
        if b.node_tree is not None and b.node_tree.animation_data is not None
    )
    return {
        "classes": sorted(n for n in dir(bpy.types) if n.startswith("CTLAB_")),
        "props": sorted(
            f"{o.__name__}.{n}"
            for o in (bpy.types.Material, bpy.types.Scene, bpy.types.WindowManager)
            for n in dir(o)
            if n.startswith("ctlab_")
        ),
        "menu": len(bpy.types.NODE_MT_add._dyn_ui_initialize()),
        "handlers": [h.__name__ for h in bpy.app.handlers.depsgraph_update_post],
        "timer": bpy.app.timers.is_registered(operators._job_tick),
        "drivers": drivers,
    }


def add_sun(scene, energy=3.0, rotation=(0.6, 0.2, 0.8)):
    data = bpy.data.lights.new("Key", 'SUN')
    data.energy = energy
    sun = bpy.data.objects.new("Key Sun", data)
    sun.rotation_euler = rotation
    scene.collection.objects.link(sun)
    return sun


def evaluate_drivers(scene):
    scene.frame_set(scene.frame_current)  # evaluates drivers
