"""Settings as data (addon/core/settings.py) and the command line that makes them: validation
once at construction, overrides, the matrix's geometry, and command lines built from the same
table the parser reads (addon/jobs/cli/options.py, addon/jobs/cli/parser.py)."""

import math

import pytest

from addon.core.errors import UserError
from addon.core.model import ModelOptions
from addon.core.settings import MatrixSettings, describe, matrix_values, with_overrides
from addon.jobs.cli.options import parse_vector
from addon.jobs.cli.parser import argv, build_parser


def test_settings_are_validated_when_made():
    with pytest.raises(UserError, match="grid 0x3 out of range"):
        MatrixSettings(rows=0, cols=3)
    with pytest.raises(UserError, match="node group has no 'reference'"):
        MatrixSettings(shader="nodes", model=ModelOptions(ibl="reference"))
    with pytest.raises(UserError, match="unknown G 'beckmann'"):
        with_overrides(MatrixSettings(), {"g_model": "beckmann"})


def test_overrides_reach_the_scene_and_the_model_and_leave_the_original():
    base = MatrixSettings(rows=3, cols=2, width=64, height=64)
    s = with_overrides(
        base, dict(g_model="smith_ggx_correlated", shader="principled", metallic=1.0, view="D")
    )
    assert (s.model.g_model, s.model.view, s.shader, s.metallic) == (
        "smith_ggx_correlated",
        "D",
        "principled",
        1.0,
    )
    assert (base.model.g_model, base.model.view, base.shader, base.metallic) == (
        "cook_torrance",
        "full",
        "osl",
        None,
    )
    assert (s.rows, s.cols, s.width) == (3, 2, 64)


def test_the_matrix_layout_metallic_by_column_smoothness_by_row():
    cells = list(matrix_values(3, 4))
    assert [c[2] for c in cells[:4]] == pytest.approx([0, 1 / 3, 2 / 3, 1])
    assert [c[3] for c in cells[::4]] == pytest.approx([1, 0.5, 0])
    d = describe(MatrixSettings(rows=3, cols=4, width=400, height=300), "x.exr")
    left, right = d["cells"][0], d["cells"][3]
    top, bottom = d["cells"][0], d["cells"][8]
    assert left["center_px"][0] < right["center_px"][0]  # metallic rises to the right
    assert top["center_px"][1] < bottom["center_px"][1]  # smoothness falls downward
    assert d["sun"]["to_light"] == pytest.approx(
        [x / math.dist((0, 0, 0), (-0.45, -0.55, 0.70)) for x in (-0.45, -0.55, 0.70)]
    )


@pytest.mark.parametrize(
    "values",
    [
        dict(sun_dir=(-0.45, -0.55, 0.7), hdri_rotation=-1e-05, sun_strength=2.5),
        dict(
            grid="2x5",
            size=96,
            samples=3,
            hdri="/tmp/a b/-odd.exr",
            hdri_strength=0.0,
            albedo=(1.0, 0.5, 0.0),
            g_model="smith_ggx_correlated",
            env_visibility=True,
        ),
    ],
)
def test_a_built_command_line_parses_back_to_its_values(values):
    """argv() writes --flag=value from the parser's own table: negative numbers and lists
    starting with "-" survive (they used to be read as options), and every value returns."""
    args = build_parser().parse_args(argv("matrix", "--out", "/tmp/x", **values))
    for dest, want in values.items():
        got = getattr(args, dest)
        if isinstance(want, tuple):
            got = parse_vector(got, 3, dest)
        assert got == pytest.approx(want) if isinstance(want, (float, tuple)) else got == want
    with pytest.raises(KeyError):
        argv("matrix", sun_direction=(0, 0, 1))  # no such option: fails here


def test_every_option_that_takes_a_value_takes_a_negative_one():
    """A typed "-0.5" or "-1,0,0" after any option of any command that takes a value is that
    value (``--flag -0.5`` is joined into ``--flag=-0.5``), read from argparse's own actions,
    not from the option table the joining is derived from: an option missing from it (the
    old hand-kept list's failure mode; mutated: dropping --seed from VALUE_FLAGS fails here)
    would be read as a flag followed by an unknown option. A switch is never joined."""
    import argparse

    from addon.jobs.cli.parser import join_negative_values

    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    seen = set()
    for name, command in sub.choices.items():
        for action in command._actions:
            if not action.option_strings or action.dest == "help":
                continue
            for flag in action.option_strings:
                seen.add(flag)
                joined = join_negative_values([flag, "-0.5,-1,2"])
                if action.nargs == 0:
                    assert joined == [flag, "-0.5,-1,2"], (name, flag)
                else:
                    assert joined == [f"{flag}=-0.5,-1,2"], (name, flag)
    assert {"--seed", "--sun-dir", "--hdri-rotation", "--metallic", "--workers"} <= seen
