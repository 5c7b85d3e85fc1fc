"""The add-on's own data-blocks are known by identity, not by name (blender/owned.py): a user's
node group, text, image, world of one of the add-on's names is never emptied, overwritten,
removed or reused, and the add-on's own block takes another name (Blender's ".001"); the
tables and bakes the node group packs into a file are checked against their files when the
file is loaded or synced, and packed again when their bytes were changed.

Mutation checks (the code before blender/owned.py): node_group._tree emptied a user's group of
each of the four names and rebuilt it with the add-on's nodes; osl_shader.shader_text
overwrote a user's text; pixel_grid.data_image removed a user's image; scene_builder.build_world
cleared a user's world; show_plot replaced a user's image's file; _float_image reused a packed
table whatever its bytes. Each test below failed there.
"""

import bpy
import numpy as np
import pytest

from addon.blender import compat, convert, model_node, node_group, owned

# the rows of docs/bad-input.md these tests hold (ID -> the test)
CASES = {
    "user-node-group-same-name": "test_a_users_node_group_of_our_name_is_kept",
    "user-node-groups-build": "test_a_build_keeps_the_users_groups_of_our_names",
    "user-text-same-name": "test_a_users_text_of_the_shaders_name_is_kept",
    "user-image-same-name": "test_a_users_image_of_a_data_images_name_is_kept",
    "user-plot-image-same-name": "test_a_users_image_of_the_plots_name_is_kept",
    "user-world-same-name": "test_a_users_world_of_the_matrix_worlds_name_is_kept",
    "packed-table-tampered": "test_a_tampered_packed_table_is_packed_again",
}

GROUP = "Cook-Torrance Lab"
NAMES = (GROUP, f"{GROUP} Light", f"{GROUP} Correction", f"{GROUP} Pre-filtered")


def _user_group(name):
    """A user's shader group: one input, one output, a Math node of theirs."""
    group = bpy.data.node_groups.new(name, "ShaderNodeTree")
    group.interface.new_socket("Mine", in_out='INPUT', socket_type="NodeSocketFloat")
    group.interface.new_socket("Out", in_out='OUTPUT', socket_type="NodeSocketFloat")
    node = group.nodes.new("ShaderNodeMath")
    node.name = "user's node"
    node.inputs[1].default_value = 0.25
    return group


def _user_material(group):
    mat = bpy.data.materials.new(f"uses {group.name}")
    compat.use_nodes(mat)
    node = mat.node_tree.nodes.new("ShaderNodeGroup")
    node.node_tree = group
    node.name = "user's group node"
    return mat


def _as_made(group, mat, name):
    """The user's group and material as the user made them."""
    assert group.name == name
    assert [n.name for n in group.nodes] == ["user's node"]
    assert group.nodes["user's node"].inputs[1].default_value == 0.25
    assert sorted(s.name for s in group.interface.items_tree) == ["Mine", "Out"]
    assert not owned.is_ours(group, node_group.TAG) and node_group.TAG not in group
    assert mat.node_tree.nodes["user's group node"].node_tree == group


@pytest.mark.parametrize("name", NAMES)
def test_a_users_node_group_of_our_name_is_kept(name):
    """A user's group named like one of the add-on's, used by their material, survives a
    conversion (ensure_group) and a second new node: same nodes, interface and material; the
    add-on's group is appended beside it under another name, ours by its mark, from the
    current sources, and holds none of the user's groups."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    user = _user_group(name)
    user_mat = _user_material(user)
    mat = bpy.data.materials.new("Converted")
    compat.use_nodes(mat)
    convert.principled_to_model(mat, scene, "nodes")
    ours = model_node.find(mat).node_tree
    assert ours != user and owned.is_ours(ours, node_group.TAG)
    assert ours.get(node_group.SOURCE_HASH) == node_group.source_digest()
    second = bpy.data.materials.new("Second")
    compat.use_nodes(second)  # 4.5 makes a material's node tree only then
    assert model_node.new_node(second.node_tree, "nodes").node_tree == ours
    held = {
        n.node_tree
        for t in bpy.data.node_groups
        if t != user
        for n in t.nodes
        if n.bl_idname == "ShaderNodeGroup"
    }
    assert user not in held
    _as_made(user, user_mat, name)


def test_a_build_keeps_the_users_groups_of_our_names():
    """build_group (a stale group rebuilt, or no cache) with users' groups of all four names:
    theirs are untouched, the add-on's four take ".001" and are found again (rebuilt in
    place, not duplicated) by a second build."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    users = {name: _user_group(name) for name in NAMES}
    mats = {name: _user_material(group) for name, group in users.items()}
    ours = node_group.build_group()
    assert ours.name == f"{GROUP}.001" and owned.is_ours(ours, node_group.TAG)
    again = node_group.build_group()
    assert again == ours and len(bpy.data.node_groups) == 8
    roles = (node_group.TAG, owned.LIGHT_GROUP, owned.CORRECTION_GROUP, owned.PREFILTERED_GROUP)
    for name, role in zip(NAMES, roles):
        _as_made(users[name], mats[name], name)
        assert owned.find(bpy.data.node_groups, name, role).name == f"{name}.001"


def test_a_users_text_of_the_shaders_name_is_kept():
    """A user's text named ctlab_cook_torrance.osl is never written: the shader's source goes
    to a text of the add-on's, found again by the next compile."""
    from addon.blender import osl_shader

    bpy.ops.wm.read_factory_settings(use_empty=True)
    user = bpy.data.texts.new(osl_shader.TEXT_NAME)
    user.from_string("// my notes\n")
    ours = osl_shader.shader_text()
    assert ours != user and ours.name == f"{osl_shader.TEXT_NAME}.001"
    assert ours.as_string() == osl_shader.source() and owned.is_ours(ours, owned.OSL_TEXT)
    assert osl_shader.shader_text() == ours and len(bpy.data.texts) == 2
    assert user.name == osl_shader.TEXT_NAME and user.as_string() == "// my notes\n"


def test_a_users_image_of_a_data_images_name_is_kept():
    """pixel_grid.data_image replaces its own earlier image of a name, never a user's."""
    from addon.blender import pixel_grid

    bpy.ops.wm.read_factory_settings(use_empty=True)
    user = bpy.data.images.new("ctlab_n", 2, 2)
    pixel_grid.data_image("ctlab_n", np.zeros((1, 1, 3)))
    ours = pixel_grid.data_image("ctlab_n", np.ones((1, 1, 3)))  # replaces the first
    assert user.name == "ctlab_n" and tuple(user.size) == (2, 2)  # not removed
    assert ours.name == "ctlab_n.001" and owned.is_ours(ours, owned.DATA_IMAGE)
    assert sorted(i.name for i in bpy.data.images) == ["ctlab_n", "ctlab_n.001"]


def test_a_users_image_of_the_plots_name_is_kept(tmp_path):
    """show_plot loads the plot into the add-on's image; a user's image named like it keeps
    its file."""
    from addon.core.files import DATA_DIR
    from addon.ui.operators import PLOT_IMAGE, show_plot

    bpy.ops.wm.read_factory_settings(use_empty=True)
    user = bpy.data.images.load(str(DATA_DIR / "seed_normal.png"))
    user.name = PLOT_IMAGE
    plot = DATA_DIR / "seed_albedo.png"
    ours = show_plot(plot)
    assert ours != user and owned.is_ours(ours, owned.PLOT_IMAGE)
    assert show_plot(plot) == ours
    assert user.name == PLOT_IMAGE and user.filepath.endswith("seed_normal.png")


def test_a_users_world_of_the_matrix_worlds_name_is_kept():
    """build_world never reuses (and clears) a user's world of its name."""
    from addon.blender import scene_builder
    from addon.blender.paths import bundled_hdri
    from addon.core.settings import MatrixSettings

    bpy.ops.wm.read_factory_settings(use_empty=True)
    user = bpy.data.worlds.new("Cook-Torrance Lab World")
    compat.use_nodes(user)
    names = sorted(n.name for n in user.node_tree.nodes)
    user.node_tree.nodes.new("ShaderNodeTexSky").name = "user's sky"
    image = scene_builder.load_image(bundled_hdri("forest"))
    ours = scene_builder.build_world(MatrixSettings(width=64, height=64), image)
    assert ours != user and owned.is_ours(ours, scene_builder.TAG)
    assert scene_builder.build_world(MatrixSettings(width=64, height=64), image) == ours
    assert sorted(n.name for n in user.node_tree.nodes) == sorted(names + ["user's sky"])


def _table_image(group):
    """A packed correction table the group reads (set_bake)."""
    trees, pending = [], [group]
    while pending:
        tree = pending.pop()
        trees.append(tree)
        pending += [n.node_tree for n in tree.nodes if n.bl_idname == "ShaderNodeGroup"]
    from addon.blender.node_compiler import MODEL_TABLE

    return next(n.image for t in trees for n in t.nodes if MODEL_TABLE in n and n.image)


def test_a_tampered_packed_table_is_packed_again(tmp_path, uniform_hdri, monkeypatch):
    """A .blend whose packed correction table was changed (other bytes under the cache's
    path) is checked when it is loaded (light_sync's load handler) and when it syncs
    (set_bake): the table is packed again from the cache's file. An untouched file is hashed
    once per loaded image and never packed again."""
    from addon.blender import light_sync
    from addon.core import ibl_bake
    from addon.core.hdri import write_float_exr

    bpy.ops.wm.read_factory_settings(use_empty=True)
    bake = ibl_bake.bake(uniform_hdri)
    group = node_group.ensure_group()
    group.use_fake_user = True
    node_group.set_bake(group, bake)
    image = _table_image(group)
    name, path = image.name, bpy.path.abspath(image.filepath)
    good = bytes(image.packed_file.data)
    assert owned.is_ours(image, owned.TABLE_IMAGE)
    clean = tmp_path / "clean.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(clean), copy=True)
    # other bytes (the table times 40) packed under the cache's path
    w, h = image.size
    pixels = np.array(image.pixels[:], dtype=np.float32).reshape(h, w, 4)[::-1, :, :3]
    bad = tmp_path / "bad.exr"
    write_float_exr(bad, pixels * 40.0)
    image.unpack(method='REMOVE')
    image.filepath = str(bad)
    image.reload()
    image.pack()
    image.filepath_raw = path
    tampered = tmp_path / "tampered.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(tampered), copy=True)

    # loaded with the add-on's handler: packed again at once
    light_sync.register_handler()
    try:
        bpy.ops.wm.open_mainfile(filepath=str(tampered))
    finally:
        light_sync.unregister_handler()
    assert bytes(bpy.data.images[name].packed_file.data) == good
    # loaded without it (ctlab scene): the sync packs it again
    bpy.ops.wm.open_mainfile(filepath=str(tampered))
    assert bytes(bpy.data.images[name].packed_file.data) != good
    node_group.set_bake(owned.find(bpy.data.node_groups, GROUP, node_group.TAG), bake)
    assert bytes(bpy.data.images[name].packed_file.data) == good
    assert abs(bpy.data.images[name].pixels[0] - pixels[-1, 0, 0]) < 1e-6

    # untouched: never packed again, hashed once per loaded image
    bpy.ops.wm.open_mainfile(filepath=str(clean))
    monkeypatch.setattr(owned, "repack", lambda image: pytest.fail(f"repacked {image.name}"))
    hashed = []
    digest = owned._digest
    monkeypatch.setattr(owned, "_digest", lambda data: hashed.append(1) or digest(data))
    assert owned.check_packed_images() == []
    first = len(hashed)
    assert first >= 1
    group = owned.find(bpy.data.node_groups, GROUP, node_group.TAG)
    node_group.set_bake(group, bake)
    node_group.set_bake(group, bake)
    assert len(hashed) == first and bpy.data.images[name] == _table_image(group)
