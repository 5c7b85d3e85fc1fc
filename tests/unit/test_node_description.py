"""The node group's description (node_groups/cook_torrance.toml) read without Blender
(core/node_description.py): the parser's grammar, every name a node uses resolving to a node,
a group input of the model's interface or the geometry, and a description that disagrees with
the model refused in one line."""

import re
import tomllib

import pytest
from hypothesis import given, settings, strategies as st

from addon.core import node_description as nd
from addon.core.errors import UserError
from addon.core.model import GROUP_INPUTS, LIGHT_SLOTS, VIEWS

GEOMETRY = {"geo.Normal", "geo.Incoming", "geo.Position"}


def test_the_parser_reads_calls_names_with_spaces_and_numbers():
    assert nd.parse("math.MULTIPLY(a, 2.5)") == (
        "call",
        "math.MULTIPLY",
        [("ref", "a"), ("num", 2.5)],
    )
    assert nd.parse("vec.SCALE(in.Sun Direction, math.ADD!(x(geo.Normal), -1e-3))") == (
        "call",
        "vec.SCALE",
        [
            ("ref", "in.Sun Direction"),
            ("call", "math.ADD!", [("call", "x", [("ref", "geo.Normal")]), ("num", -1e-3)]),
        ],
    )


@pytest.mark.parametrize(
    "text", ["math.ADD(a", "f(", "f(a b (", "", "f(,)", "f(a) g", "f(1 2)", "f(a))", ")"]
)
def test_a_malformed_expression_is_one_line(text):
    with pytest.raises(UserError, match="node description"):
        nd.parse(text)


@settings(max_examples=300, deadline=None)
@given(st.text(alphabet="abxy_.!() ,-0123456789e", max_size=30))
def test_any_text_parses_or_is_refused_in_one_line(text):
    try:
        tree = nd.parse(text)
    except UserError:
        return
    assert tree[0] in ("call", "ref", "num")


def _refs(tree):
    if tree[0] == "ref":
        yield tree[1]
    elif tree[0] == "call":
        files = 1 if tree[1] in ("env", "table") else 0  # a baked file's name comes first
        for arg in tree[2][files:]:
            yield from _refs(arg)


def test_every_name_resolves():
    """Read from the TOML itself: each node's references are the description's own nodes,
    inputs the model's interface declares, the geometry, or (in per-light frames) the light's
    fields, which the key Sun's [lights] table defines (a baked file's name aside)."""
    data = nd.load_description()
    nodes = {n for f in data["frames"].values() for n in f["nodes"]}
    inputs = {f"in.{i.group}" for i in GROUP_INPUTS}
    light_fields = {f"light.{f}" for f in data["lights"]["key"]}
    texts = [
        (f.get("per_light", False), t) for f in data["frames"].values() for t in f["nodes"].values()
    ]
    texts += [(False, t) for t in data["views"].values()]
    texts += [(False, data["scene"][k]) for k in nd.SCENE_EXPRESSIONS]
    unknown = set()
    for per_light, text in texts:
        for ref in _refs(nd.parse(text)):
            known = nodes | inputs | GEOMETRY | (light_fields if per_light else set())
            if ref not in known:
                unknown.add(ref)
    assert not unknown, sorted(unknown)


def test_the_light_plan_has_one_instance_per_slot_and_the_key_sun():
    plan = nd.LightPlan(nd.load_description())
    assert plan.slots == LIGHT_SLOTS
    # the per-light group's inputs start with the light's fields, each a slot input
    slot_inputs = {i.group for i in GROUP_INPUTS}
    assert all(f"Light 1 {f}" in slot_inputs for f in plan.fields)
    exprs = plan.main_exprs()
    for name, _ in plan.outputs:
        if "." in name:
            continue
        for suffix in [""] + [f"_{i}" for i in range(1, LIGHT_SLOTS + 1)]:
            assert exprs[name + suffix] == ("lights", ("light", suffix, name))


def test_a_description_that_disagrees_with_the_model_is_refused(tmp_path):
    text = nd.DESCRIPTION.read_text()
    data = tomllib.loads(text)
    first, second = list(data["views"])[:2]
    assert list(data["views"]) == list(VIEWS)
    # the first two views swapped: the View input's numbers would select the wrong term
    lines = text.splitlines(keepends=True)
    start = next(i for i, ln in enumerate(lines) if ln.strip() == "[views]")
    a = next(i for i in range(start, len(lines)) if lines[i].startswith(f"{first} ="))
    b = next(i for i in range(start, len(lines)) if lines[i].startswith(f"{second} ="))
    lines[a], lines[b] = lines[b], lines[a]
    bad = tmp_path / "swapped.toml"
    bad.write_text("".join(lines))
    with pytest.raises(UserError, match="views must be"):
        nd.load_description(bad)
    wrong_slots = tmp_path / "slots.toml"
    wrong_slots.write_text(re.sub(r"(?m)^slots = \d+", f"slots = {LIGHT_SLOTS + 1}", text))
    with pytest.raises(UserError, match="light slots"):
        nd.load_description(wrong_slots)
