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
        nodes.append(model_node.find(mat))
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

    from addon.blender import materials
    from addon.core.model import Lighting, ModelOptions

    scene, sphere = sun_lit_sphere(24)
    options, lighting = ModelOptions(ibl="split_sum"), Lighting(**SUN_LIT)
    mat = materials.model_material("sphere", "osl", options, lighting, metallic=0.5)
    node_setup(model_node.find(mat))
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
