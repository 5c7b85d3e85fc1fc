"""The add-on's material tools as an artist uses them, driven headless through bpy.ops in a
factory-startup scene: registration and its exact removal, new materials (following the Sun
and the world), the Add-menu node group and textures, Principled <-> Cook-Torrance
conversion (undo, round trip), the implementation switch and the view on all materials."""

import bpy
import pytest
from mathutils import Vector

from addon.blender import compat, convert, model_node, osl_shader, scene_lights
from addon.core.model import LIGHT_TYPE_CODES
from addon.ui import register, panels as ui
from ui_helpers import add_sun, draw, evaluate_drivers, registered_state


def test_register_unregister_reregister_leaves_nothing():
    bpy.ops.wm.read_factory_settings(use_empty=False)
    before = registered_state()
    assert not before["classes"] and not before["props"], before
    register.register()
    during = registered_state()
    assert "CTLAB_PT_material" in during["classes"] and "CTLAB_OT_new_material" in during["classes"]
    assert during["menu"] == before["menu"] + 1 and "on_depsgraph_update" in during["handlers"]
    assert "Material.ctlab_view" in during["props"]
    register.unregister()
    register.register()
    assert registered_state() == during
    register.unregister()
    assert registered_state() == before


def test_new_material_follows_the_sun_and_world(addon):
    scene = bpy.context.scene
    sun = add_sun(scene)
    cube = bpy.data.objects["Cube"]
    bpy.context.view_layer.objects.active = cube
    for impl, kind in (("nodes", "ShaderNodeGroup"), ("osl", "ShaderNodeGroup")):
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
            assert osl_shader.socket(node, "hdri").default_value.endswith(".exr")
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
        evaluate_drivers(scene)
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
    assert osl_shader.socket(node, "g_model").default_value == "smith_ggx_correlated"


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
    add_sun(scene)
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


def _aovs(mat):
    return [n for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeOutputAOV"]


@pytest.mark.parametrize("impl", ["nodes", "osl"])
def test_the_residual_pass_is_opt_in(addon, impl):
    """A converted material (scene transport) feeds no AOV Output until the scene asks for the
    residual albedo pass: an AOV Output makes Cycles' SVM compute everything that feeds it at
    every camera hit, before any closure is skipped (bench/results.md). Asked for, each such
    material gets one AOV Output of the pass (not a second when asked again), the view layer
    its AOV, a switch of implementation keeps it (and the Correction Depth); switching the
    material to the lab transport or the scene's pass off removes that node and leaves a
    user's AOV Output of the same pass name, fed by the same output, where it is."""
    from addon.blender import light_sync
    from addon.core.model import OSL_RESIDUAL

    scene = bpy.context.scene
    cube = bpy.data.objects["Cube"]
    bpy.context.view_layer.objects.active = cube
    cube.select_set(True)
    mat = _user_principled(cube)
    assert bpy.ops.ctlab.convert_to_cook_torrance(scope='ACTIVE', implementation=impl) == {
        'FINISHED'
    }
    node = model_node.find(mat)
    assert model_node.get_option(node, "light_transport") == "scene"
    assert _aovs(mat) == [] and not scene.ctlab_residual_pass
    assert OSL_RESIDUAL not in scene.view_layers[0].aovs

    scene.ctlab_residual_pass = True
    scene.ctlab_residual_pass = True
    (aov,) = _aovs(mat)
    assert aov.aov_name == OSL_RESIDUAL
    assert aov.inputs["Color"].links[0].from_socket == model_node.residual_output(node)
    assert OSL_RESIDUAL in scene.view_layers[0].aovs
    light_sync.sync_material(mat, scene, environment=False)
    assert len(_aovs(mat)) == 1
    other = "osl" if impl == "nodes" else "nodes"
    model_node.transport_input(node, "correction_depth").default_value = 5
    assert bpy.ops.ctlab.switch_implementation(target=other) == {'FINISHED'}
    node = model_node.find(mat)
    assert model_node.transport_input(node, "correction_depth").default_value == 5
    (aov,) = _aovs(mat)
    assert aov.inputs["Color"].links[0].from_socket == model_node.residual_output(node)

    mine = mat.node_tree.nodes.new("ShaderNodeOutputAOV")  # the user's own
    mine.aov_name = OSL_RESIDUAL
    mat.node_tree.links.new(model_node.residual_output(node), mine.inputs["Color"])
    mat.ctlab_light_transport = "lab"
    assert _aovs(mat) == [mine]
    mat.ctlab_light_transport = "scene"
    assert len(_aovs(mat)) == 2
    scene.ctlab_residual_pass = False
    assert _aovs(mat) == [mine] and mine.inputs["Color"].is_linked
