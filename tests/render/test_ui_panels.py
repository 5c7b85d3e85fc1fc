"""The add-on's panels and preferences as an artist sees them: every panel's draw for a
model material, another material and none (checked against Blender's RNA), the preferences
read by the operators, the transport notes and warnings of the material panel, and light
sync's report."""

import types

import bpy

from addon.blender import model_node
from addon.ui import operators, preferences, panels as ui
from ui_helpers import StubLayout, draw


def test_panels_draw_for_model_other_and_no_material(addon):
    scene = bpy.context.scene
    cube = bpy.data.objects["Cube"]
    bpy.context.view_layer.objects.active = cube
    principled = cube.active_material
    bpy.ops.ctlab.new_material(implementation="nodes")
    nodes_mat = cube.active_material
    bpy.ops.ctlab.new_material(implementation="osl")
    osl_mat = cube.active_material
    seen = {}
    for label, mat in (
        ("nodes", nodes_mat),
        ("osl", osl_mat),
        ("principled", principled),
        ("none", None),
    ):
        assert ui.CTLAB_PT_material.poll(types.SimpleNamespace(object=cube, material=mat))
        for panel in ui.PANELS:
            seen[label, panel.__name__] = draw(panel, object=cube, material=mat)
    model_calls = seen["nodes", "CTLAB_PT_material"]
    assert ("prop", "ctlab_view") in model_calls and ("prop", "ctlab_ibl") in model_calls
    assert ("operator", "ctlab.switch_implementation") in model_calls
    assert any("Roughness 0.500" in c[1] for c in model_calls if c[0] == "label")
    assert ("prop", "ctlab_energy") in model_calls
    assert ("operator", "ctlab.brdf_plot") in model_calls
    # the startup file's Point light is shaded, unshadowed by the node group (it says so)
    labels = [c[1] for c in model_calls if c[0] == "label"]
    assert "Other lights: 1 shaded (of 8 slots)" in labels and "  Light" in labels
    assert any("node group's lights cast no shadows" in t for t in labels)
    assert not any("cast no shadows" in c[1] for c in seen["osl", "CTLAB_PT_material"])
    assert ("operator", "ctlab.convert_to_cook_torrance") in seen["principled", "CTLAB_PT_material"]
    assert ("operator", "ctlab.new_material") in seen["none", "CTLAB_PT_material"]
    scene.render.engine = 'CYCLES'
    scene.cycles.shading_system = False
    osl_calls = draw(ui.CTLAB_PT_material, object=cube, material=osl_mat)
    assert any("OSL cannot run: Open Shading Language is off" in c[1] for c in osl_calls)


def test_preferences_draw_and_are_read(addon, tmp_path):
    entry = bpy.context.preferences.addons.new()  # enabled under the package's name
    entry.module = preferences.PACKAGE
    try:
        prefs = preferences.get()
        assert isinstance(prefs, preferences.CTLAB_AddonPreferences)
        layout = StubLayout()

        class Panel:  # the preferences with a stub layout
            def __getattr__(self, name):
                return layout if name == "layout" else getattr(prefs, name)

        preferences.CTLAB_AddonPreferences.draw(Panel(), bpy.context)
        assert [c[1] for c in layout.calls] == ["implementation", "hdri", "cache_folder", "samples"]
        prefs.implementation = "osl"
        cube = bpy.data.objects["Cube"]
        bpy.context.view_layer.objects.active = cube
        bpy.ops.ctlab.new_material()  # the preferences' implementation
        assert model_node.implementation(model_node.find(cube.active_material)) == "osl"
    finally:
        bpy.context.preferences.addons.remove(entry)


def test_the_panel_says_what_each_transport_sees_and_warns_of_inexact_settings(addon):
    """The material panel's transport box: Lab says what it does not see and why term views
    and Unity units need it; Scene names the render settings that keep it from being exact
    (the startup file's Cycles defaults clamp indirect light at 10 and filter glossy at 1)
    and falls silent once the jobs' exact settings are set."""
    from addon.blender import renderer

    scene = bpy.context.scene
    cube = bpy.data.objects["Cube"]
    bpy.context.view_layer.objects.active = cube
    bpy.ops.ctlab.new_material(implementation="osl")
    mat = cube.active_material
    scene.render.engine = 'CYCLES'

    def labels():
        return [
            c[1] for c in draw(ui.CTLAB_PT_material, object=cube, material=mat) if c[0] == "label"
        ]

    assert mat.ctlab_light_transport == "scene"  # the UI's default
    calls = draw(ui.CTLAB_PT_material, object=cube, material=mat)
    assert ("prop", "default_value") in calls  # the node's Correction Depth
    assert ("prop", "ctlab_residual_pass") in calls
    text = labels()
    assert any(t.startswith("Scene: path traced by Cycles") for t in text)
    (warning,) = [t for t in text if t.startswith("Not exact with")]
    assert "Clamp Indirect 10" in warning and "Filter Glossy 1" in warning
    renderer.set_exact_path_tracing(scene)
    assert not any(t.startswith("Not exact with") for t in labels())
    mat.ctlab_g_model = "cook_torrance"
    assert any("correction emission" in t for t in labels())
    mat.ctlab_units = "unity"
    assert any("Unity units exist in Lab only" in t for t in labels())
    mat.ctlab_units = "physical"
    mat.ctlab_view = "D"
    assert any("is the lab's: a term view is a BRDF value" in t for t in labels())
    mat.ctlab_light_transport = "lab"
    text = labels()
    assert any("does not see other objects" in t for t in text)
    assert any(t.startswith("Term views and Unity units need Lab") for t in text)
    assert not any(t.startswith("Not exact with") for t in text)


def test_light_sync_reports_slot_lights_without_a_key_sun(addon):
    """The startup file has a Point light and no Sun: light sync's report says there is no
    key Sun and names the Point light in a slot; with a Sun added, the Sun is the key light
    and the Point stays in its slot. A material whose emission someone set to be sampled as a
    light is set back to None by the sync (a view or a correction is never a lamp)."""
    cube = bpy.data.objects["Cube"]
    bpy.context.view_layer.objects.active = cube
    bpy.ops.ctlab.new_material(implementation="nodes")
    mat = cube.active_material
    assert mat.cycles.emission_sampling == 'NONE'
    mat.cycles.emission_sampling = 'AUTO'
    scene = bpy.context.scene
    assert (
        operators.sync_summary(scene, 1)
        == "1 material follow no key Sun; 1 light in slots (Light) and the world"
    )
    assert bpy.ops.ctlab.sync_lighting() == {'FINISHED'}
    assert mat.cycles.emission_sampling == 'NONE'
    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", 'SUN'))
    scene.collection.objects.link(sun)
    assert (
        operators.sync_summary(scene, 2)
        == "2 materials follow the key Sun Sun; 1 light in slots (Light) and the world"
    )
