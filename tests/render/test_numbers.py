"""Numbers and options on the command line: negative components parse (argparse read them as
options), every number takes ASCII digits only (int() and float() accept other scripts' digits,
str.isdigit accepts '²'), in every parser and every Unicode digit class (Hypothesis), and a
NaN/Inf HDRI is refused by every job. Refusals render nothing; the one render is tiny."""

import json
import unicodedata

import numpy as np
import pytest
from hypothesis import given, strategies as st

from helpers import FAST, TINY, one_line, tiny_hdri
from addon.core import paths
from addon.core.errors import UserError
from addon.jobs import cli
from addon.jobs.cli.options import parse_grid, parse_vector

# The option checks: the same on every Blender series, so run on one
# (docs/testing.md, "Which tests run on both series").
pytestmark = pytest.mark.one_series

RENDER = ["render", "--shader", "nodes", "--view", "NdotL", *TINY]
SMALL = ["--grid", "2x2", "--size", "32", "--samples", "1"]


def test_negative_values_parse_and_render(tmp_path, capsys):
    """The documented syntax with negative components, as the add-on's default Sun has them:
    argparse used to read "-0.45,..." as an option ("expected one argument")."""
    out = tmp_path / "out"
    code = cli.main(
        [
            "render",
            "--shader",
            "nodes",
            "--view",
            "NdotL",
            *SMALL,
            "--out",
            str(out),
            "--sun-dir",
            "-0.45,-0.55,0.70",
            "--hdri-rotation",
            "-1e-05",
        ]
    )
    assert code == 0, capsys.readouterr().err
    scene = json.loads((out / "scene.json").read_text())
    want = np.array([-0.45, -0.55, 0.70]) / np.linalg.norm([-0.45, -0.55, 0.70])
    np.testing.assert_allclose(scene["sun"]["to_light"], want, rtol=1e-6)
    assert scene["hdri_rotation_deg"] == pytest.approx(-1e-05)


@pytest.mark.parametrize(
    "argv",
    [
        ["--grid", "²x2"],
        ["--grid", "2x٣"],
        ["--size", "٣٢"],
        ["--samples", "１"],
        ["--seed", "७"],
        ["--sun-strength", "٣"],
        ["--sun-dir", "0,0,١"],
        ["--albedo", "0.5,0.5,0.٥"],
        ["--size", "3_2"],
    ],
)
def test_numbers_take_ascii_digits_only(argv, tmp_path, capsys):
    """str.isdigit accepts '²' and int() refuses it (a traceback on 5.2); int() and float()
    accept other scripts' digits and '_': every number is ASCII digits, else one line."""
    one_line(
        capsys,
        cli.main(["render", "--shader", "nodes", *TINY, *argv, "--out", str(tmp_path / "o")]),
    )
    assert not (tmp_path / "o").exists()


def test_plot_numbers_take_ascii_digits_only(tmp_path, capsys):
    one_line(capsys, cli.main(["plot", "--metallic", "٠.5", "--out", str(tmp_path / "o")]))


DIGITS = st.characters(categories=("Nd", "No", "Nl"))


@FAST
@given(
    digits=st.lists(st.one_of(DIGITS, st.sampled_from("0123456789")), min_size=1, max_size=4).map(
        "".join
    )
)
def test_numbers_in_every_unicode_digit_class(digits):
    """Accepted exactly when every digit is ASCII, in every parser of numbers."""
    ascii_only = all(c in "0123456789" for c in digits)
    for parse in (paths.ascii_int, paths.ascii_float):
        try:
            value = parse(digits)
        except ValueError:
            assert not ascii_only, digits
        else:
            assert ascii_only and value == int(digits), digits
    try:
        parse_grid(f"{digits}x1")
        assert ascii_only
    except UserError:
        assert not ascii_only
    try:
        parse_vector(f"{digits},0,1", 3, "sun direction")
        assert ascii_only
    except UserError:
        assert not ascii_only


def test_unicode_digit_classes_are_covered():
    """The strategy above reaches the classes named above (a sanity check on it)."""
    assert unicodedata.category("²") == "No" and unicodedata.category("٣") == "Nd"
    assert "²".isdigit() and not "²".isdecimal()


@pytest.mark.parametrize("job", ["render", "bake"])
def test_a_nan_hdri_is_refused_by_every_job(job, tmp_path, capsys):
    hdri = str(tiny_hdri(tmp_path / "nan.exr", nan=True))
    argv = (
        RENDER + ["--hdri", hdri, "--out", str(tmp_path / "o")]
        if job == "render"
        else ["bake", hdri, "--out", str(tmp_path / "o")]
    )
    one_line(capsys, cli.main(argv), "1 NaN/Inf pixel(s)")
    assert not (tmp_path / "o").exists()
