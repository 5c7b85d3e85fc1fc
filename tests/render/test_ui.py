"""The add-on as an artist uses it, driven headless through bpy.ops in a factory-startup scene:
registration and its exact removal, new materials, the Add-menu node group, Principled <->
Cook-Torrance conversion (undo, round trip), the view on all materials, light and world sync,
every panel's draw, and the comparison job in the background (progress, cancel)."""

import json
import math
import types

import bpy
import pytest
from mathutils import Vector

from addon.blender import compat, convert, model_node, scene_lights


# ----------------------------------------------------------------------------------------

from addon.core.model import LIGHT_TYPE_CODES
from addon.ui import operators, preferences, register, panels as ui


# ----------------------------------------------------------------------------------------
# A layout that checks every call against Blender's RNA (a real UILayout needs a window)

_ICONS = set(bpy.types.UILayout.bl_rna.functions["label"].parameters["icon"].enum_items.keys())


def _operator_rna(idname):
    module, name = idname.split(".")
    return getattr(getattr(bpy.ops, module), name).get_rna_type()  # raises when unknown


class _OperatorProps:
    def __init__(self, idname):
        object.__setattr__(self, "_rna", _operator_rna(idname))

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
        assert kw.get("icon", 'NONE') in _ICONS, kw.get("icon")

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
        return _OperatorProps(idname)

    def operator_menu_enum(self, idname, prop, **kw):
        assert _operator_rna(idname).properties[prop].type == 'ENUM'
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


# ----------------------------------------------------------------------------------------


def _registered_state():
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


def _sun(scene, energy=3.0, rotation=(0.6, 0.2, 0.8)):
    data = bpy.data.lights.new("Key", 'SUN')
    data.energy = energy
    sun = bpy.data.objects.new("Key Sun", data)
    sun.rotation_euler = rotation
    scene.collection.objects.link(sun)
    return sun


def _evaluate(scene):
    scene.frame_set(scene.frame_current)  # evaluates drivers


def test_register_unregister_reregister_leaves_nothing():
    bpy.ops.wm.read_factory_settings(use_empty=False)
    before = _registered_state()
    assert not before["classes"] and not before["props"], before
    register.register()
    during = _registered_state()
    assert "CTLAB_PT_material" in during["classes"] and "CTLAB_OT_new_material" in during["classes"]
    assert during["menu"] == before["menu"] + 1 and "on_depsgraph_update" in during["handlers"]
    assert "Material.ctlab_view" in during["props"]
    register.unregister()
    register.register()
    assert _registered_state() == during
    register.unregister()
    assert _registered_state() == before


def test_new_material_follows_the_sun_and_world(addon):
    scene = bpy.context.scene
    sun = _sun(scene)
    cube = bpy.data.objects["Cube"]
    bpy.context.view_layer.objects.active = cube
    for impl, kind in (("nodes", "ShaderNodeGroup"), ("osl", "ShaderNodeScript")):
        assert bpy.ops.ctlab.new_material(implementation=impl) == {'FINISHED'}
        mat = cube.active_material
        node = model_node.find(mat)
        assert node.bl_idname == kind and model_node.implementation(node) == impl
        out = next(n for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeOutputMaterial")
        assert out.inputs["Surface"].links[0].from_node == node
        if impl == "osl":  # the OSL shader reads its normal from the geometry
            assert (
                model_node.surface_input(node, "normal").links[0].from_node.bl_idname
                == "ShaderNodeNewGeometry"
            )
            assert model_node.get_option(node, "ibl") == "reference"
            assert node.inputs["HDRI"].default_value.endswith(".exr")
        else:
            assert model_node.get_option(node, "ibl") == "split_sum"
        paths = {fc.data_path for fc in mat.node_tree.animation_data.drivers}
        slot_paths = {
            p
            for p in paths
            if node.path_from_id() not in p
            or node.inputs[int(p.split("inputs[")[1].split("]")[0])].name.startswith("Light 1 ")
        }
        # Sun Direction, Sun Irradiance, HDRI Strength; the startup file's Point light holds
        # slot 1 (position, direction, colour, radius; and its shadow switch in OSL)
        assert len(paths - slot_paths) == 3
        assert len(slot_paths) == (5 if impl == "osl" else 4), sorted(slot_paths)
        assert scene_lights.slot_type(node, 1) == LIGHT_TYPE_CODES["POINT"]
        sun.data.energy = 5.0
        sun.rotation_euler = (0.3, -0.4, 1.0)
        _evaluate(scene)
        expected = sun.matrix_world.to_quaternion() @ Vector((0, 0, 1))
        got = node.inputs["Sun Direction"].default_value
        assert max(abs(a - b) for a, b in zip(got, expected)) < 1e-5, (tuple(got), expected)
        assert abs(node.inputs["Sun Irradiance"].default_value[0] - 5.0) < 1e-6
        sun.data.energy = 3.0
    # the node is what the Material dropdowns read and write
    mat.ctlab_view = "D"
    assert model_node.get_option(node, "view") == "D" and mat.ctlab_view == "D"
    assert mat.ctlab_g_model == "cook_torrance"
    mat.ctlab_g_model = "smith_ggx_correlated"
    assert node.inputs["G"].default_value == "smith_ggx_correlated"


def test_add_menu_node_group_and_textures(addon):
    cube = bpy.data.objects["Cube"]
    mat = cube.active_material
    before = len(mat.node_tree.nodes)
    assert draw(ui.draw_add_menu) == [("operator", "ctlab.add_node_group")]
    assert bpy.ops.ctlab.add_node_group() == {'FINISHED'}
    node = model_node.find(mat)
    assert node is not None and len(mat.node_tree.nodes) == before + 1
    assert node.node_tree.name == "Cook-Torrance Lab" and mat.node_tree.nodes.active == node
    assert bpy.ops.ctlab.add_texture(slot="normal") == {'FINISHED'}
    src = model_node.surface_input(node, "normal").links[0].from_node
    assert (
        src.bl_idname == "ShaderNodeNormalMap"
        and src.inputs["Color"].links[0].from_node.bl_idname == "ShaderNodeTexImage"
    )
    assert bpy.ops.ctlab.add_texture(slot="albedo") == {'FINISHED'}
    assert (
        model_node.surface_input(node, "albedo").links[0].from_node.bl_idname
        == "ShaderNodeTexImage"
    )
    group_nodes = len(node.node_tree.nodes)
    groups = len(bpy.data.node_groups)  # the group and its sub-groups
    assert bpy.ops.ctlab.add_node_group() == {'FINISHED'}  # the group is reused, not rebuilt
    assert len(bpy.data.node_groups) == groups and len(node.node_tree.nodes) == group_nodes
    assert model_node.surface_input(node, "albedo").is_linked


def _principled_state(mat):
    bsdf = convert.surface_principled(mat)
    values = {
        s.name: (tuple(s.default_value) if hasattr(s.default_value, "__len__") else s.default_value)
        for s in bsdf.inputs
        if hasattr(s, "default_value") and s.enabled
    }
    links = sorted(
        (l.from_node.name, l.from_socket.name, l.to_node.bl_idname, l.to_socket.name)
        for l in mat.node_tree.links
    )
    return values, links


def _user_principled(cube):
    mat = bpy.data.materials.new("User Paint")
    compat.use_nodes(mat)
    cube.data.materials.clear()
    cube.data.materials.append(mat)
    nt = mat.node_tree
    bsdf = nt.nodes["Principled BSDF"]
    colour = nt.nodes.new("ShaderNodeTexImage")
    colour.name = "Paint Colour"
    colour.image = bpy.data.images.new("paint", 8, 8)
    rough = nt.nodes.new("ShaderNodeTexImage")
    rough.name = "Paint Roughness"
    nmap = nt.nodes.new("ShaderNodeNormalMap")
    nt.links.new(colour.outputs["Color"], bsdf.inputs["Base Color"])
    nt.links.new(rough.outputs["Color"], bsdf.inputs["Roughness"])
    nt.links.new(nmap.outputs["Normal"], bsdf.inputs["Normal"])
    bsdf.inputs["Metallic"].default_value = 0.7
    bsdf.inputs["Coat Weight"].default_value = 0.5
    return mat


def test_conversion_round_trip_and_undo(addon):
    scene = bpy.context.scene
    cube = bpy.data.objects["Cube"]
    bpy.context.view_layer.objects.active = cube
    cube.select_set(True)
    mat = _user_principled(cube)
    original = _principled_state(mat)
    assert convert.principled_to_model(mat.copy(), scene, "nodes") == ["coat"]  # reported

    bpy.ops.ed.undo_push(message="before conversion")
    # as a button press does: with an undo push (a script's bpy.ops call makes none)
    assert bpy.ops.ctlab.convert_to_cook_torrance('EXEC_DEFAULT', True, scope='SELECTED') == {
        'FINISHED'
    }
    mat = bpy.data.materials["User Paint"]
    node = model_node.find(mat)
    assert convert.surface_principled(mat) is None and node is not None
    assert model_node.surface_input(node, "albedo").links[0].from_node.name == "Paint Colour"
    assert abs(model_node.surface_input(node, "metallic").default_value - 0.7) < 1e-7
    invert = model_node.surface_input(node, "smoothness").links[0].from_node
    assert invert.bl_idname == "ShaderNodeMath" and invert.operation == 'SUBTRACT'
    assert invert.inputs[1].links[0].from_node.name == "Paint Roughness"
    assert (
        model_node.surface_input(node, "normal").links[0].from_node.bl_idname
        == "ShaderNodeNormalMap"
    )
    assert mat.cycles.emission_sampling == 'NONE'

    bpy.ops.ed.undo()  # the conversion was one undo step
    mat = bpy.data.materials["User Paint"]
    assert model_node.find(mat) is None and _principled_state(mat)[1] == original[1]
    bpy.ops.ed.redo()
    mat = bpy.data.materials["User Paint"]
    assert model_node.find(mat) is not None

    assert bpy.ops.ctlab.convert_to_principled(scope='ACTIVE') == {'FINISHED'}
    mat = bpy.data.materials["User Paint"]
    values, links = _principled_state(mat)
    assert links == original[1]  # the same textures on the same inputs, no helper
    for name in ("Base Color", "Metallic", "Roughness", "Normal"):
        a, b = values[name], original[0][name]
        assert (
            (a == b)
            if isinstance(a, str)
            else max(
                abs(x - y) for x, y in zip(*(v if isinstance(v, tuple) else (v,) for v in (a, b)))
            )
            < 1e-6
        )
    assert not any(model_node.implementation(n) for n in mat.node_tree.nodes)
    assert mat.cycles.emission_sampling == 'AUTO'

    # values (not links) survive the round trip exactly as well
    bsdf = convert.surface_principled(mat)
    for link in list(mat.node_tree.links):
        if link.to_node == bsdf and link.to_socket.name == "Roughness":
            mat.node_tree.links.remove(link)
    bsdf.inputs["Roughness"].default_value = 0.3
    bpy.ops.ctlab.convert_to_cook_torrance(implementation="osl")
    node = model_node.find(bpy.data.materials["User Paint"])
    assert model_node.implementation(node) == "osl"
    # an artist's material: the scene transport, its correction 1 + 1 samples per shading point
    assert model_node.get_option(node, "light_transport") == "scene"
    assert node.inputs["Env Samples"].default_value == 1
    assert abs(model_node.surface_input(node, "smoothness").default_value - 0.7) < 1e-6
    bpy.ops.ctlab.convert_to_principled()
    bsdf = convert.surface_principled(bpy.data.materials["User Paint"])
    assert abs(bsdf.inputs["Roughness"].default_value - 0.3) < 1e-6
    with pytest.raises(RuntimeError, match="not use the Cook-Torrance model"):
        bpy.ops.ctlab.convert_to_principled()


def test_switch_implementation_and_view_on_all(addon):
    scene = bpy.context.scene
    _sun(scene)
    cube = bpy.data.objects["Cube"]
    bpy.context.view_layer.objects.active = cube
    bpy.ops.ctlab.new_material(implementation="osl", light_transport="lab")
    mat = cube.active_material
    node = model_node.find(mat)
    assert node.inputs["Env Samples"].default_value == 4  # the lab's reference integration
    img = bpy.data.images.new("albedo", 4, 4)
    tex = mat.node_tree.nodes.new("ShaderNodeTexImage")
    tex.image = img
    mat.node_tree.links.new(tex.outputs["Color"], model_node.surface_input(node, "albedo"))
    model_node.surface_input(node, "metallic").default_value = 0.25
    mat.ctlab_diffuse_model = "lambert"
    scene.render.engine = compat.eevee_engine_id()
    assert "EEVEE cannot run OSL" in model_node.osl_unavailable_reason(scene)
    assert bpy.ops.ctlab.switch_implementation(target="nodes") == {'FINISHED'}
    node = model_node.find(mat)
    assert model_node.implementation(node) == "nodes"
    assert model_node.surface_input(node, "albedo").links[0].from_node == tex
    assert abs(model_node.surface_input(node, "metallic").default_value - 0.25) < 1e-7
    assert model_node.get_option(node, "diffuse_model") == "lambert"
    assert not model_node.surface_input(node, "normal").is_linked
    assert all(
        fc.data_path.startswith('nodes["Cook-Torrance"]')
        for fc in mat.node_tree.animation_data.drivers
    )
    # the Sun 3 + 3, the strength, the Point light (slot 1): position, direction, colour 3 each,
    # radius; no stale ones
    assert len(mat.node_tree.animation_data.drivers) == 17

    scene.render.engine = 'CYCLES'
    scene.cycles.shading_system = False
    assert "Open Shading Language is off" in model_node.osl_unavailable_reason(scene)
    bpy.ops.ctlab.new_material(implementation="nodes")
    assert bpy.ops.ctlab.set_view_all(view="spec_color") == {'FINISHED'}
    assert [model_node.get_option(n, "view") for _, n in model_node.model_materials()] == [
        "spec_color",
        "spec_color",
    ]


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


def test_render_comparison_in_the_background(addon, tmp_path):
    """The job runs in another process: progress rises to 1, the report is written; a second
    job cancelled after its first render keeps that render whole and leaves no partial file."""
    import time

    wm = bpy.context.window_manager
    kw = dict(rows=2, cols=2, size=32, samples=2, open_report=False)

    def run_until(done, limit=300):
        start = time.monotonic()
        seen = []
        while time.monotonic() - start < limit:
            operators._job_tick()  # what the timer calls (no event loop headless)
            seen.append(wm.ctlab_job_progress)
            if done():
                return seen
            time.sleep(0.2)
        raise AssertionError(f"timed out: {wm.ctlab_job_message}")

    # the scene a user has after Build Sphere Matrix: its default Sun has negative x and y
    # (which the job's command line used to misread), a world with strength and rotation
    assert bpy.ops.ctlab.build_sphere_matrix(rows=2, cols=2, resolution=32) == {'FINISHED'}
    background, mapping = (
        next(n for n in bpy.context.scene.world.node_tree.nodes if n.bl_idname == kind)
        for kind in ("ShaderNodeBackground", "ShaderNodeMapping")
    )
    background.inputs["Strength"].default_value = 1.5
    mapping.inputs["Rotation"].default_value[2] = -0.5  # radians
    sun = next(o for o in bpy.context.scene.objects if o.type == 'LIGHT' and o.data.type == 'SUN')
    to_light = tuple(sun.matrix_world.to_quaternion() @ Vector((0.0, 0.0, 1.0)))
    assert min(to_light[:2]) < 0
    out = tmp_path / "full"
    assert bpy.ops.ctlab.render_comparison(directory=str(out), **kw) == {'FINISHED'}
    with pytest.raises(RuntimeError, match="already running"):
        bpy.ops.ctlab.render_comparison(directory=str(out), **kw)
    seen = run_until(lambda: operators.JOBS["comparison"].state != "running")
    job = operators.JOBS["comparison"]
    assert job.state == "done", "\n".join(job.lines[-20:])
    assert wm.ctlab_job_progress == 1.0 and (out / "report.html").is_file()
    assert seen == sorted(seen) and len(set(seen)) >= 3, seen  # it moved, never backwards
    scene = json.loads((out / "cook_torrance" / "scene.json").read_text())
    assert scene["sun"]["to_light"] == pytest.approx(to_light, abs=1e-6)
    assert scene["sun"]["irradiance"] == pytest.approx([sun.data.energy] * 3)
    assert scene["hdri_strength"] == pytest.approx(1.5)
    assert scene["hdri_rotation_deg"] == pytest.approx(math.degrees(-0.5))
    assert scene["hdri"].endswith("forest.exr")
    assert not bpy.app.timers.is_registered(operators._job_tick) or operators._job_tick() is None

    out = tmp_path / "cancelled"
    bpy.ops.ctlab.render_comparison(directory=str(out), **kw)
    run_until(lambda: (out / "cook_torrance" / "scene.json").is_file())
    assert bpy.ops.ctlab.cancel_comparison() == {'FINISHED'}
    run_until(lambda: operators.JOBS["comparison"].state == "cancelled", limit=60)
    from addon.core.compare import read_image

    assert read_image(out / "cook_torrance" / "render.exr").shape == (32, 32, 3)
    assert not (out / "report.html").exists()
    # nothing half-written; the task graph's markers (.tasks/) record the renders that
    # finished, so a rerun resumes (docs/usage.md, "Batch jobs as task graphs")
    leftovers = [
        p.name
        for p in out.rglob("*")
        if "partial" in p.name or (p.name.startswith(".") and p.name != ".tasks")
    ]
    assert not leftovers, leftovers
    assert all(m.suffix == ".json" for m in (out / ".tasks").iterdir())

    with pytest.raises(RuntimeError, match="output folder not writable"):
        bpy.ops.ctlab.render_comparison(directory="/proc/ctlab", **kw)


def test_brdf_plot_of_the_active_material(addon, tmp_path):
    """BRDF Plot runs ``ctlab plot`` on the material's own values and switches in another
    process and loads plot.png as the image "Cook-Torrance BRDF Plot" (reloaded by a second
    plot); a linked input is reported and plotted at its socket's value; a material that is
    not the model cannot be plotted."""
    import time

    cube = bpy.data.objects["Cube"]
    bpy.context.view_layer.objects.active = cube
    bpy.ops.ctlab.new_material(implementation="nodes")
    mat = cube.active_material
    node = model_node.find(mat)
    model_node.surface_input(node, "metallic").default_value = 1.0
    model_node.surface_input(node, "smoothness").default_value = 0.7
    model_node.surface_input(node, "albedo").default_value = (1.0, 0.5, 0.2, 1.0)
    model_node.set_option(node, "g_model", "smith_ggx_correlated")

    def plot(out, **kw):
        assert bpy.ops.ctlab.brdf_plot(directory=str(out), **kw) == {'FINISHED'}
        start = time.monotonic()
        while operators.JOBS["plot"].poll() == "running":
            assert time.monotonic() - start < 300, operators.JOBS["plot"].lines[-10:]
            time.sleep(0.2)
        operators._job_tick()
        job = operators.JOBS["plot"]
        assert job.state == "done", "\n".join(job.lines[-20:])
        return json.loads((out / "plot.json").read_text())

    data = plot(tmp_path / "a")
    p = data["parameters"]
    assert (p["metallic"], p["smoothness"], p["g_model"], p["shader"]) == (
        1.0,
        pytest.approx(0.7),
        "smith_ggx_correlated",
        "nodes",
    )
    assert p["albedo"] == pytest.approx([1.0, 0.5, 0.2])
    image = bpy.data.images[operators.PLOT_IMAGE]
    from addon.core.compare import read_image

    h, w, _ = read_image(tmp_path / "a" / "plot.png").shape
    assert tuple(image.size) == (w, h)
    assert bpy.context.window_manager.ctlab_plot_state == "done"

    # a textured smoothness: plotted at the socket's value, with a warning
    tex = mat.node_tree.nodes.new("ShaderNodeValue")
    tex.outputs[0].default_value = 0.1
    mat.node_tree.links.new(tex.outputs[0], model_node.surface_input(node, "smoothness"))
    data = plot(tmp_path / "b", compare_g=True)
    assert data["parameters"]["smoothness"] == pytest.approx(0.7)
    assert [v["tag"] for v in data["variants"]] == ["", "g-cook_torrance", "g-unity_smith_joint"]
    assert bpy.data.images[operators.PLOT_IMAGE].filepath.endswith("b/plot.png")
    argv, notes = operators.plot_command(node, tmp_path)
    assert any("smoothness is linked" in n for n in notes)

    # a plot that fails in its process (a folder where it writes lobe.svg) says why, and
    # the image keeps the last plot
    (tmp_path / "d" / "lobe.svg").mkdir(parents=True)
    assert bpy.ops.ctlab.brdf_plot(directory=str(tmp_path / "d")) == {'FINISHED'}
    start = time.monotonic()
    while operators.JOBS["plot"].poll() == "running":
        assert time.monotonic() - start < 300
        time.sleep(0.2)
    operators._job_tick()
    wm = bpy.context.window_manager
    assert (
        wm.ctlab_plot_state == "failed" and "holds a folder named lobe.svg" in wm.ctlab_plot_message
    ), wm.ctlab_plot_message
    assert not (tmp_path / "d" / "plot.json").exists()
    assert bpy.data.images[operators.PLOT_IMAGE].filepath.endswith("b/plot.png")

    cube.active_material = bpy.data.materials["Material"]
    with pytest.raises(RuntimeError, match="poll"):
        bpy.ops.ctlab.brdf_plot(directory=str(tmp_path / "c"))


def test_scene_comparison_in_the_background(addon, tmp_path):
    """Compare Scene with Principled: the open scene (never written) through its camera, its
    Cook-Torrance material against the Principled conversion, in a background process; the
    report and the per-material metrics are written and the file's copy is removed."""
    import time
    from addon.blender import demo_scene, light_sync, materials
    from addon.core.model import ModelOptions

    scene, sphere, _other = demo_scene.build("hdri", 48, 36)
    register_scene = bpy.context.scene
    assert register_scene == scene
    mat = materials.model_material(
        "CT",
        "nodes",
        ModelOptions(
            light_transport="scene",
            g_model="smith_ggx_correlated",
            diffuse_model="lambert",
            ibl="split_sum",
        ),
        **demo_scene.METAL,
    )
    demo_scene.set_material(sphere, mat)
    light_sync.sync_material(mat, scene)
    out = tmp_path / "scene"
    # the operator's overrides reach the command line: here the OSL shader for the node
    # group's material (Smith and Lambert: the closures are the model exactly)
    assert bpy.ops.ctlab.scene_comparison(
        directory=str(out),
        size=48,
        samples=4,
        shader="osl",
        g_model="smith_ggx_correlated",
        camera="Camera",
        open_report=False,
    ) == {'FINISHED'}
    job = operators.JOBS["comparison"]
    command = " ".join(job.process.args)
    assert "'--shader=osl'" in command and "'--g=smith_ggx_correlated'" in command
    assert "'--camera=Camera'" in command and "--diffuse" not in command
    start = time.monotonic()
    while job.poll() in ("running", "cancelling") and time.monotonic() - start < 300:
        operators._job_tick()
        time.sleep(0.2)
    operators._job_tick()
    assert job.state == "done", "\n".join(job.lines[-20:])
    assert (out / "report.html").is_file()
    metrics = json.loads((out / "metrics.json").read_text())
    (entry,) = [m for m in metrics["materials"] if m["name"] == "CT"]
    assert entry["pixels"] > 50 and entry["ciede2000_mean"] < 2.0
    assert not job.staging.exists()


def test_a_scene_comparison_needs_a_camera(addon):
    with pytest.raises(RuntimeError, match="no camera named 'Cube'"):
        bpy.ops.ctlab.scene_comparison(size=32, samples=1, camera="Cube")
    with pytest.raises(RuntimeError, match="no camera named 'Nowhere'"):
        bpy.ops.ctlab.scene_comparison(size=32, samples=1, camera="Nowhere")
    bpy.ops.wm.read_factory_settings(use_empty=True)
    with pytest.raises(RuntimeError, match="no camera"):
        bpy.ops.ctlab.scene_comparison(size=32, samples=1)


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
