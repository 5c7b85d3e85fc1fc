"""The model's interface is written once (addon/core/model/interface.py): the OSL shader's
parameters, the node group's sockets and the views of both implementations must be exactly that
table."""

import re
import tomllib

import bpy
import pytest

from helpers import ROOT
from addon.blender import model_node, node_group, osl_shader
from addon.core import node_description, osl_source
from addon.core.model import (
    GROUP_INPUTS,
    GROUP_OUTPUTS,
    INPUTS,
    OPTION_VALUES,
    OSL_INPUTS,
    OSL_OUTPUTS,
    VIEWS,
)

SHADER = osl_source.source()  # the shader with its parts inlined


@pytest.fixture(scope="module")
def osl_node():
    bpy.ops.wm.read_factory_settings(use_empty=True)
    mat = bpy.data.materials.new("interface")
    if mat.node_tree is None:
        mat.use_nodes = True
    node = mat.node_tree.nodes.new("ShaderNodeScript")
    osl_shader.compile_script_node(node)
    return node


def _value(sock):
    v = sock.default_value
    return tuple(v) if hasattr(v, "__len__") and not isinstance(v, str) else v


def test_the_osl_shaders_parameters_are_the_table(osl_node):
    """Every parameter the compiled shader has is in the table under its name, with the
    table's label and default; and every OSL input of the table is a parameter."""
    got = {s.identifier: s for s in osl_node.inputs}
    assert set(got) == {i.osl for i in OSL_INPUTS}
    for i in OSL_INPUTS:
        sock = got[i.osl]
        assert sock.name == i.label, i.key
        if i.key in ("normal", "tex_bottom_up"):
            continue  # the geometry's N; set for the running Blender when compiled
        want = i.values[i.default] if i.values else i.default
        have = _value(sock)
        if isinstance(want, tuple):
            assert have == pytest.approx(want[: len(have)]), i.key
        else:
            assert have == pytest.approx(want) if isinstance(want, float) else have == want, (
                i.key,
                have,
                want,
            )
    assert [s.identifier for s in osl_node.outputs] == list(OSL_OUTPUTS)


def test_the_osl_shader_offers_exactly_the_views_and_switch_values():
    """The string values the shader compares its view and switches with are the table's."""
    code = re.sub(r"//[^\n]*", "", SHADER)
    views = set(re.findall(r'\bview\s*[!=]=\s*"(\w+)"', code))
    assert views == set(VIEWS)
    for key in ("g_model", "diffuse_model", "units", "ibl"):
        compared = set(re.findall(rf'\b{key}\s*[!=]=\s*"(\w+)"', code))
        assert compared and compared <= set(OPTION_VALUES[key]), (key, compared)


def test_the_node_groups_sockets_are_the_table():
    group = node_group.build_group("interface test")
    inputs = [
        s for s in group.interface.items_tree if s.item_type == 'SOCKET' and s.in_out == 'INPUT'
    ]
    outputs = [
        s for s in group.interface.items_tree if s.item_type == 'SOCKET' and s.in_out == 'OUTPUT'
    ]
    assert [s.name for s in inputs] == [i.group for i in GROUP_INPUTS]
    assert [s.socket_type for s in inputs] == [
        node_group.SOCKET_TYPES[i.kind] for i in GROUP_INPUTS
    ]
    for sock, i in zip(inputs, GROUP_INPUTS):
        assert sock.description == i.tooltip
        if i.kind in ("FLOAT", "INT"):
            assert (sock.min_value, sock.max_value) == pytest.approx((i.min, i.max)), i.key
    assert [(s.name, s.socket_type) for s in outputs] == [
        (n, node_group.SOCKET_TYPES[k]) for n, k in GROUP_OUTPUTS
    ]
    data = tomllib.loads((ROOT / "node_groups" / "cook_torrance.toml").read_text())
    assert list(data["views"]) == list(VIEWS)
    used = set(re.findall(r"in\.([A-Za-z][\w ]*?)(?=[,)])", str(data)))
    assert used <= {i.group for i in GROUP_INPUTS}, used - {i.group for i in GROUP_INPUTS}
    bpy.data.node_groups.remove(group)


def test_every_option_round_trips_through_both_implementations(osl_node):
    """model_node writes and reads every value of every switch and view on both; the node
    group refuses the reference indirect light with a message."""
    from addon.core.errors import UserError

    tree = osl_node.id_data
    group = model_node.new_node(tree, "nodes")
    for node in (osl_node, group):
        for key, values in OPTION_VALUES.items():
            for value in values:
                if model_node.implementation(node) == "nodes" and value == "reference":
                    with pytest.raises(UserError, match="no 'reference' indirect light"):
                        model_node.set_option(node, key, value)
                    continue
                model_node.set_option(node, key, value)
                assert model_node.get_option(node, key) == value
    assert {i.key for i in INPUTS} >= set(OPTION_VALUES)


@pytest.mark.parametrize(
    "view_text",
    ["vec.SCALE(direct, 0.5)", "vec.ADD(direct, direct)", "vec.MULTIPLY(indirect, indirect)"],
)
def test_a_closure_term_outside_a_sum_is_refused(monkeypatch, view_text):
    """The group's Emission output adds each closure term (gated, prefiltered) once with the
    weight of the views that hold it, so a view may hold one only once and only as a term of
    a sum; otherwise its Emission and Value outputs would silently differ. The shipped
    description builds (every other test); these do not."""
    from addon.blender import node_group
    from addon.core.errors import UserError

    data = node_description.load_description()
    views = dict(data["views"], full=view_text)
    monkeypatch.setattr(node_group, "load_description", lambda *a: dict(data, views=views))
    with pytest.raises(UserError, match="at most once, as a term of a sum"):
        node_group.build_group("ctlab test group")


def _choices(parser, command: str, dest: str):
    sub = next(a for a in parser._actions if a.dest == "command").choices[command]
    return tuple(next(a for a in sub._actions if a.dest == dest).choices or ())


def test_the_cli_and_the_ui_take_their_vocabulary_from_the_model():
    """The implementations, the reference and every switch's values are core/model/words.py's:
    the command line's choices, the material panel's dropdowns, the preferences' and the
    operators' items are built from it, in its order, named by ui/labels.py."""
    from addon.core import model
    from addon.jobs.cli.parser import build_parser
    from addon.ui import operators, preferences, properties
    from addon.ui.labels import label

    parser = build_parser()
    assert _choices(parser, "render", "shader") == model.SHADERS == ("osl", "nodes", "principled")
    assert _choices(parser, "plot", "shader") == model.IMPLEMENTATIONS
    assert _choices(parser, "scene", "shader") == model.IMPLEMENTATIONS
    for key, dest in (
        ("g_model", "g_model"),
        ("diffuse_model", "diffuse_model"),
        ("energy", "energy"),
        ("light_transport", "light_transport"),
    ):
        assert _choices(parser, "scene", dest) == OPTION_VALUES[key], key
    for key, items in (
        ("view", properties.VIEW_ITEMS),
        ("g_model", properties.G_ITEMS),
        ("diffuse_model", properties.DIFFUSE_ITEMS),
        ("units", properties.UNITS_ITEMS),
        ("energy", properties.ENERGY_ITEMS),
        ("ibl", properties.IBL_ITEMS),
        ("light_transport", properties.TRANSPORT_ITEMS),
    ):
        assert tuple(i[0] for i in items) == OPTION_VALUES[key], key
        assert all(i[1] == label(i[0]) for i in items), key
    assert {i[0] for i in preferences.IMPLEMENTATION_ITEMS} == set(model.IMPLEMENTATIONS)
    assert tuple(i[0] for i in operators._SHADER_ITEMS) == model.SHADERS


def test_each_implementation_gets_the_indirect_light_and_files_it_can_use():
    from addon.core.model import BAKED_IBL_MODES, IBL_MODES, files_needed, indirect_light

    assert indirect_light("osl") == "reference"
    assert indirect_light("nodes") == "split_sum"
    assert indirect_light("nodes", "reference") == "split_sum"  # the group has no MC
    for mode in IBL_MODES:
        assert indirect_light("osl", mode) == mode
        assert indirect_light("nodes", mode) == (mode if mode in BAKED_IBL_MODES else "split_sum")
    assert files_needed("osl", "reference", "lab") == {"tables"}
    assert files_needed("osl", "split_sum", "lab") == {"bake"}
    assert files_needed("osl", "unity", "scene") == {"bake", "tables"}  # the correction
    assert files_needed("nodes", "split_sum", "scene") == {"bake"}
    assert files_needed("principled", "split_sum", "lab") == set()
