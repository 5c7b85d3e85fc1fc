"""What a new material costs after the first: the node group shipped built, or built once
and then appended from the cache (blender/node_group.py ``ensure_group``), the OSL shader compiled
once per node with nothing left in TMPDIR (blender/osl_shader.py), and the conversion keeping
Principled's energy behaviour (blender/convert.py ``ENERGY_OF``). Mechanisms, not timings:
the timings are in bench/results.md."""

import tempfile

import bpy
import pytest

from addon.blender import compat, convert, model_node, node_group


def _groups():
    return sorted(g.name for g in bpy.data.node_groups)


def _shape(group):
    """Nodes and links of the group and the groups it holds, by name."""
    seen, pending = {}, [group]
    while pending:
        tree = pending.pop()
        if tree.name not in seen:
            seen[tree.name] = (len(tree.nodes), len(tree.links))
            pending += [
                n.node_tree
                for n in tree.nodes
                if n.bl_idname == "ShaderNodeGroup" and n.node_tree is not None
            ]
    return seen


@pytest.fixture
def builds(monkeypatch, tmp_path):
    """An empty cache of its own, no shipped group, and a count of the node group's builds."""
    monkeypatch.setenv("CTLAB_CACHE", str(tmp_path / "cache"))
    monkeypatch.setattr(node_group, "SHIPPED_SOURCES", tmp_path / "no-shipped-group.json")
    count = {"builds": 0}
    build = node_group.build_group

    def counted(*args, **kw):
        count["builds"] += 1
        return build(*args, **kw)

    monkeypatch.setattr(node_group, "build_group", counted)
    return count


def _material(name):
    mat = bpy.data.materials.new(name)
    compat.use_nodes(mat)
    return mat


def test_the_node_group_is_built_once_then_appended(builds, tmp_path):
    """The first ensure_group builds the group (1,271 nodes in four groups) and caches it;
    a second material in the same file reuses the same datablock (no build, no new group);
    a new file (a task's fresh scene) appends it from the cache: no build, the same nodes and
    links, ours (tag and source hash), no fake user. A damaged cache entry is never used: the
    group is built again. Mutation check: with ``_append_cached`` returning None, the fresh
    file builds a second time and this test fails."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    first = node_group.ensure_group()
    assert builds["builds"] == 1
    shape, names = _shape(first), _groups()
    assert len(names) == 4 and sum(n for n, _ in shape.values()) > 1000
    entry = tmp_path / "cache" / node_group.cache_key(node_group.source_digest())
    assert (entry / node_group.GROUP_FILE).is_file()

    a, b = (model_node.new_node(_material(n).node_tree, "nodes") for n in ("A", "B"))
    assert a.node_tree == b.node_tree == first and builds["builds"] == 1
    assert _groups() == names

    bpy.ops.wm.read_factory_settings(use_empty=True)
    assert not bpy.data.node_groups
    appended = node_group.ensure_group()
    assert builds["builds"] == 1  # appended, not built
    assert _groups() == names and _shape(appended) == shape
    assert appended.get(node_group.TAG) and not appended.use_fake_user
    assert appended.get(node_group.SOURCE_HASH) == node_group.source_digest()
    assert model_node.new_node(_material("C").node_tree, "nodes").node_tree == appended

    bpy.ops.wm.read_factory_settings(use_empty=True)
    blend = entry / node_group.GROUP_FILE
    blend.write_bytes(blend.read_bytes()[:1000])  # damaged: the manifest no longer matches
    assert _shape(node_group.ensure_group()) == shape
    assert builds["builds"] == 2  # built again, not read from the damaged file


# What describes a node besides its place on the canvas and its selection
_LAYOUT = {"location", "width", "height", "select", "name", "hide", "show_options",
           "show_preview", "show_texture", "mute", "color", "use_custom_color", "dimensions",
           "width_hidden", "location_absolute", "bl_width_default", "bl_height_default",
           "bl_width_min", "bl_width_max", "bl_height_min", "bl_height_max"}  # fmt: skip


_ITEM_VALUES = ("default_value", "min_value", "max_value")


def _value(v):
    return tuple(v) if hasattr(v, "__len__") and not isinstance(v, str) else v


def _describe(group):
    """Every tree of the group (named without the group's own name): its interface, and
    each node's type, settings, parent, sub-group and unlinked input values, and the links."""
    base, out, pending = group.name, {}, [group]
    while pending:
        tree = pending.pop()
        key = tree.name.replace(base, "<group>")
        if key in out:
            continue
        items = [
            (i.item_type, i.name, getattr(i, "in_out", None), getattr(i, "socket_type", None))
            + tuple(_value(getattr(i, a, None)) for a in _ITEM_VALUES)
            for i in tree.interface.items_tree
        ]
        nodes = {}
        for n in tree.nodes:
            settings = {
                p.identifier: _value(getattr(n, p.identifier))
                for p in n.bl_rna.properties
                if p.identifier not in _LAYOUT
                and not p.is_readonly
                and p.type in {"ENUM", "BOOLEAN", "INT", "FLOAT", "STRING"}
            }
            inputs = [
                (i.identifier, i.is_linked, _value(getattr(i, "default_value", None)))
                for i in n.inputs
            ]
            sub = getattr(n, "node_tree", None)
            nodes[n.name] = (
                n.bl_idname,
                settings,
                n.parent.name if n.parent else None,
                sub.name.replace(base, "<group>") if sub else None,
                inputs,
                dict(n.items()),  # our tags
            )
            if sub is not None:
                pending.append(sub)
        links = sorted(
            (lk.from_node.name, lk.from_socket.identifier, lk.to_node.name, lk.to_socket.identifier)
            for lk in tree.links
        )
        tags = {k: v for k, v in tree.items() if k != node_group.SOURCE_HASH}
        out[key] = (items, nodes, links, tags)
    return out


def test_the_shipped_group_is_the_build_and_is_appended_without_one(monkeypatch, tmp_path):
    """The extension ships the group (addon/data/node_group.blend, scripts/build_node_group.py
    with 4.5): built from the current sources, so that a first use with an empty cache appends
    it in a fraction of a second and builds nothing; and, read by this Blender, node for
    node what build_group makes here from the description: every tree's interface, every
    node's type, settings, frame, sub-group, input values and tags, every link. Mutation
    check: a changed default in the description fails the digest, and a node changed in the
    shipped file fails the comparison."""
    assert node_group.shipped_digest() == node_group.source_digest(), (
        "the shipped node group is stale: run CTLAB_BLENDER=4.5 ./scripts/dev.sh build_node_group"
    )
    monkeypatch.setenv("CTLAB_CACHE", str(tmp_path / "cache"))
    monkeypatch.setattr(node_group, "_store", lambda *a: None)
    bpy.ops.wm.read_factory_settings(use_empty=True)
    build = node_group.build_group
    monkeypatch.setattr(node_group, "build_group", lambda *a, **k: pytest.fail("built"))
    shipped = node_group.ensure_group()
    assert shipped.get(node_group.SOURCE_HASH) == node_group.source_digest()
    assert shipped.get(node_group.TAG) and not shipped.use_fake_user
    built = build("ctlab build check")
    want, got = _describe(built), _describe(shipped)
    assert list(want) == list(got)
    for tree in want:
        assert want[tree][0] == got[tree][0], (tree, "interface")
        assert want[tree][1].keys() == got[tree][1].keys(), (tree, "nodes")
        for name, node in want[tree][1].items():
            assert node == got[tree][1][name], (tree, name)
        assert want[tree][2] == got[tree][2], (tree, "links")
        assert want[tree][3] == got[tree][3], (tree, "tags")


def test_an_osl_node_leaves_nothing_in_tmpdir(monkeypatch, tmp_path):
    """Cycles compiles a script node through temporary .osl/.oso files and leaves the .oso
    in TMPDIR, also when only the node's script is set (its update compiles it). Every
    compile of ours happens in a private folder, removed after: TMPDIR stays empty over a
    conversion to OSL (three materials). And the shader is compiled once: the later nodes get
    the first's bytecode and sockets, the same as a compile gives. Mutation checks: setting
    the node's script before entering the private folder (as before) left one .oso per
    material here; without the compiled shader kept, three compiles."""
    from cycles import osl as cycles_osl

    from addon.blender import osl_shader

    tmp = tmp_path / "tmpdir"
    tmp.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(tmp))
    monkeypatch.setattr(osl_shader, "_COMPILED", {})  # as in a new process
    compiles = []
    compile_ = cycles_osl.osl_compile
    monkeypatch.setattr(cycles_osl, "osl_compile", lambda *a: compiles.append(a) or compile_(*a))
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.engine = 'CYCLES'  # the script node's update compiles with Cycles
    nodes = []
    for name in ("A", "B", "C"):
        mat = _material(name)
        assert convert.principled_to_model(mat, scene, "osl") == []
        assert model_node.implementation(model_node.find(mat)) == "osl"
        nodes.append(osl_shader.script_node(model_node.find(mat)))
    assert sorted(p.name for p in tmp.iterdir()) == []
    # compiled once: the later nodes get the first's bytecode and the same sockets
    assert len(compiles) == 1 and scene.render.engine == 'CYCLES'

    def sockets(node):
        return [
            (s.identifier, s.bl_idname, s.name, _value(getattr(s, "default_value", None)))
            for s in (*node.inputs, *node.outputs)
        ]

    assert len({n.bytecode_hash for n in nodes}) == 1 and nodes[0].bytecode
    assert sockets(nodes[0]) == sockets(nodes[1]) == sockets(nodes[2])
    assert len(sockets(nodes[0])) > 100
    # and before any value is set: a node compiled anew against one given the compiled shader
    osl_shader._COMPILED.clear()
    tree = _material("D").node_tree
    compiled, given = (tree.nodes.new("ShaderNodeScript") for _ in range(2))
    osl_shader.compile_script_node(compiled)
    osl_shader.compile_script_node(given)
    assert len(compiles) == 2 and sockets(compiled) == sockets(given)


@pytest.mark.parametrize("impl", ["nodes", "osl"])
def test_conversion_keeps_principleds_energy(impl):
    """Principled's Multiscatter GGX (Blender's default) becomes energy compensated and its
    single-scatter GGX energy none, so a converted rough metal keeps the light that Principled
    keeps (docs/model.md "energy"); the way back gives the distribution again. Mutation
    check: without the energy setting every conversion read the model's default, none, and
    the Multiscatter case failed."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    for distribution, energy in (('MULTI_GGX', "compensated"), ('GGX', "none")):
        mat = _material(distribution)
        convert.surface_principled(mat).distribution = distribution
        assert convert.principled_to_model(mat, scene, impl) == []  # nothing to report
        assert model_node.get_option(model_node.find(mat), "energy") == energy
        convert.model_to_principled(mat)
        assert convert.surface_principled(mat).distribution == distribution


def _render_sphere(node_setup, tmp_path, name):
    """A render of a sphere lit by the key Sun alone (no world: nothing sampled), its model
    node an OSL node that ``node_setup`` gives its bytecode."""
    from helpers import SUN_LIT, render_still, sun_lit_sphere

    from addon.blender import materials, osl_shader
    from addon.core.model import Lighting, ModelOptions

    scene, sphere = sun_lit_sphere(24)
    options, lighting = ModelOptions(ibl="split_sum"), Lighting(**SUN_LIT)
    mat = materials.model_material("sphere", "osl", options, lighting, metallic=0.5)
    node_setup(osl_shader.script_node(model_node.find(mat)))
    sphere.data.materials.append(mat)
    return render_still(scene, tmp_path / f"{name}.exr")


def test_the_stored_bytecode_is_portable(tmp_path):
    """A script node stores the shader without oslc's comment lines and %filename hints
    (osl_shader.portable_bytecode): 30% smaller in every saved .blend, no path of this
    machine in it (the compile's temporary folder, Blender's stdosl.h, the repository), the
    same text in every process, and Cycles' hash of it. It is the same shader: a sphere
    rendered with it equals the sphere rendered with Cycles' own compile (bit for bit on 5.2;
    within 2e-6 on 4.5, whose renders of one shader differ by 4e-7 from run to run).
    Mutation check: storing what Cycles' compile gives (as before) fails the first
    assertions (4,600 comment lines, the temporary .osl's path)."""
    import hashlib
    import os

    from cycles import osl as cycles_osl

    from addon.blender import osl_shader

    kept = {}

    def ours(node):
        kept["bytecode"], kept["hash"] = node.bytecode, node.bytecode_hash

    ours_pixels = _render_sphere(ours, tmp_path, "ours")
    bytecode = kept["bytecode"]
    assert bytecode.startswith("OpenShadingLanguage ") and "\nshader cook_torrance" in bytecode
    assert not [line for line in bytecode.splitlines() if line.startswith("#")]
    for path in (tempfile.gettempdir(), os.getcwd(), os.path.dirname(bpy.__file__)):
        assert path not in bytecode
    assert "%filename" not in bytecode and "%line{" in bytecode
    assert kept["hash"] == hashlib.md5(bytecode.encode()).hexdigest()

    def cycles_own(node):
        saved, tempfile.tempdir = tempfile.tempdir, str(tmp_path)  # where its .oso is left
        try:
            ok, _, full, full_hash = cycles_osl.update_internal_script(lambda *a: None, node.script)
        finally:
            tempfile.tempdir = saved
        assert ok and len(full) > len(bytecode) * 1.3
        assert osl_shader.portable_bytecode(full) == bytecode
        node.bytecode, node.bytecode_hash = full, full_hash

    cycles_pixels = _render_sphere(cycles_own, tmp_path, "cycles")
    # bit for bit on 5.2; 4.5 renders one shader twice within 4e-7 of itself
    assert ours_pixels.max() > 0.05
    assert abs(ours_pixels - cycles_pixels).max() <= (0.0 if bpy.app.version >= (5, 0) else 2e-6)


def _script_nodes():
    """Every script node of the file: in materials and in node groups."""
    trees = [m.node_tree for m in bpy.data.materials if m.node_tree] + list(bpy.data.node_groups)
    return [n for t in trees for n in t.nodes if n.bl_idname == "ShaderNodeScript"]


def test_osl_materials_share_one_compiled_shader(tmp_path):
    """A script node stores the compiled shader (628 kB of the model's) in the .blend once per
    node: 20 OSL materials made a 16.1 MB file (bench/results.md). The model's OSL node is a
    group node whose group holds the script node (osl_shader.shared_group), the strings (view,
    switches, files) on the script node, every other input on the group node: materials with
    the same strings share one group, one copy. Checked: 20 converted materials hold one
    script node between them and save, uncompressed, in under 2 MB, each keeping its own
    Metallic; one given another view gets a group of its own while the 19 keep theirs and
    their view, and going back rejoins the shared group (the group made in between, unused,
    is removed); a user's node group of the shared group's name is never used or changed.
    Mutation check: a script node per material (as before) fails the count and the size."""
    from addon.blender import osl_shader

    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    users_group = bpy.data.node_groups.new(osl_shader.GROUP_NAME, "ShaderNodeTree")
    mats = []
    for i in range(20):
        mat = _material(f"M{i:02d}")
        convert.surface_principled(mat).inputs["Metallic"].default_value = i / 19
        assert convert.principled_to_model(mat, scene, "osl") == []
        mats.append(mat)
    nodes = [model_node.find(m) for m in mats]
    assert all(model_node.implementation(n) == "osl" for n in nodes)
    shared = nodes[0].node_tree
    assert all(n.node_tree == shared for n in nodes) and shared != users_group
    assert users_group.name == osl_shader.GROUP_NAME and len(users_group.nodes) == 0
    assert len(_script_nodes()) == 1 and len(_script_nodes()[0].bytecode) > 500_000
    metallic = [model_node.surface_input(n, "metallic").default_value for n in nodes]
    assert metallic == pytest.approx([i / 19 for i in range(20)])
    path = tmp_path / "twenty.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path), compress=False, copy=True)
    assert path.stat().st_size < 2_000_000, path.stat().st_size

    model_node.set_option(nodes[3], "view", "D")
    own = nodes[3].node_tree
    assert own != shared and model_node.get_option(nodes[3], "view") == "D"
    assert model_node.surface_input(nodes[3], "metallic").default_value == pytest.approx(3 / 19)
    others = [n for n in nodes if n != nodes[3]]
    assert all(n.node_tree == shared and model_node.get_option(n, "view") == "full" for n in others)
    assert len(_script_nodes()) == 2
    model_node.set_option(nodes[3], "view", "full")
    assert nodes[3].node_tree == shared and len(_script_nodes()) == 1
    assert model_node.surface_input(nodes[3], "metallic").default_value == pytest.approx(3 / 19)
    assert len(users_group.nodes) == 0 and users_group.users == 0

    # a new node starts from the shader's own strings, not another material's files
    assert osl_shader.socket(nodes[0], "tables").default_value
    fresh = model_node.new_node(_material("fresh").node_tree, "osl")
    assert osl_shader.socket(fresh, "tables").default_value == ""
    assert model_node.get_option(fresh, "view") == "full"
    fresh.id_data.nodes.remove(fresh)

    # a copy the user makes of the shared group (it keeps the add-on's mark) and edits is
    # theirs: still the model, never changed, shared or removed
    mine = shared.copy()
    mine.name = "My shader"
    mine.nodes.new("ShaderNodeRGB")
    nodes[5].node_tree = mine
    assert model_node.implementation(nodes[5]) == "osl"
    model_node.set_option(nodes[5], "view", "NdotL")
    assert nodes[5].node_tree != mine and model_node.get_option(nodes[5], "view") == "NdotL"
    assert osl_shader.socket(nodes[5], "view").id_data != mine
    assert osl_shader.script_node(nodes[7]).inputs["View"].default_value == "full"
    model_node.set_option(nodes[5], "view", "full")
    assert nodes[5].node_tree == shared and mine.name in bpy.data.node_groups
    assert len(mine.nodes) == 4 and osl_shader.script_node(nodes[0]).id_data == shared
    nodes[6].node_tree = mine
    model_node.set_option(nodes[8], "view", "D")  # another group is made, not the user's used
    assert nodes[8].node_tree not in (mine, shared) and mine.users == 1
    kept = shared.copy()  # renamed, not edited: the user's all the same
    kept.name = "Kept"
    nodes[9].node_tree = kept
    model_node.set_option(nodes[9], "view", "G")
    assert (
        nodes[9].node_tree != kept
        and kept.nodes[osl_shader.SCRIPT_NODE].inputs["View"].default_value == "full"
    )
    assert "Kept" in bpy.data.node_groups and kept.users == 0


def test_a_script_node_of_an_earlier_version_is_still_the_model():
    """Files of earlier versions hold a bare script node in each OSL material: it is still
    the model's node (the panel, the sync and the jobs find it), its own strings change with
    set_option and the world's files, and no shared group is made for it."""
    from addon.blender import osl_shader
    from addon.core.model import Lighting

    bpy.ops.wm.read_factory_settings(use_empty=True)
    mat = _material("old")
    mat.node_tree.nodes.clear()
    node = mat.node_tree.nodes.new("ShaderNodeScript")
    osl_shader.compile_script_node(node)
    assert model_node.find(mat) == node and model_node.implementation(node) == "osl"
    model_node.set_option(node, "view", "NdotL")
    model_node.set_lighting(node, Lighting())
    assert node.inputs["View"].default_value == "NdotL"
    assert model_node.get_option(node, "view") == "NdotL"
    assert node.inputs["Tables Folder"].default_value  # set_environment's folder of tables
    model_node.surface_input(node, "metallic").default_value = 0.25
    assert node.inputs["Metallic"].default_value == 0.25
    assert not [g for g in bpy.data.node_groups if g.name.startswith(osl_shader.GROUP_NAME)]


def test_an_osl_material_linked_from_a_library_is_the_model(tmp_path):
    """A material linked from another .blend is read like a local one (the export reads
    linked materials): its node, though its shared group is the library's, is the model's."""
    from addon.blender import materials, osl_shader
    from addon.core.model import Lighting, ModelOptions

    bpy.ops.wm.read_factory_settings(use_empty=True)
    mat = materials.model_material(
        "shared", "osl", ModelOptions(view="D"), Lighting(), metallic=0.3
    )
    mat.use_fake_user = True  # saved without an object
    library = tmp_path / "library.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(library), copy=True)
    bpy.ops.wm.read_factory_settings(use_empty=True)
    with bpy.data.libraries.load(str(library), link=True) as (data_from, data_to):
        data_to.materials = ["shared"]
    (mat,) = data_to.materials
    node = model_node.find(mat)
    assert mat.library is not None and node is not None
    assert model_node.implementation(node) == "osl" and model_node.get_option(node, "view") == "D"
    assert model_node.surface_input(node, "metallic").default_value == pytest.approx(0.3)
    assert osl_shader.script_node(node).id_data.library is not None


def test_a_shared_group_of_an_earlier_shader_is_recompiled_once_keeping_values(monkeypatch):
    """A file saved by another version holds a shared group whose script is an older source:
    user_blend.refresh_osl recompiles it once for all its materials (in place: the group is
    the add-on's), each keeping its own values and its output link."""
    from addon.blender import osl_shader, user_blend

    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    mats = []
    for i in range(3):
        mat = _material(f"R{i}")
        convert.surface_principled(mat).inputs["Metallic"].default_value = 0.2 * (i + 1)
        assert convert.principled_to_model(mat, scene, "osl") == []
        mats.append(mat)
    nodes = [model_node.find(m) for m in mats]
    group = nodes[0].node_tree
    script = osl_shader.script_node(nodes[0])
    # the file's text holds the earlier source (the bytecode is the earlier compile's)
    script.script.from_string(script.script.as_string() + "\n// an earlier version\n")
    assert script.script.as_string() != osl_shader.source()
    calls = []
    compile_ = osl_shader.compile_script_node
    monkeypatch.setattr(
        osl_shader, "compile_script_node", lambda node, *a: calls.append(node) or compile_(node)
    )
    user_blend.refresh_osl(nodes)
    assert len(calls) == 1 and all(n.node_tree == group for n in nodes)
    assert script.script.as_string() == osl_shader.source()
    assert group[osl_shader.SOURCE] == osl_shader.text_digest(script.script)
    for i, node in enumerate(nodes):
        assert model_node.surface_input(node, "metallic").default_value == pytest.approx(
            0.2 * (i + 1)
        )
        assert model_node.shader_output(node).is_linked
