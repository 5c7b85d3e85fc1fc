"""A randomised argument fuzzer (Hypothesis) over the command line, run in-process (cli.main,
what scripts/ctlab.py exits with): whatever the arguments, the command exits 0 or 2; on 2 it
prints exactly one line on stderr and no traceback; and it writes nothing outside --out (the
folder it runs in is listed before and after; the cache is the session's, elsewhere)."""

from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

from addon.jobs import cli

# Argparse and the option checks: the same on every Blender series, so run on one
# (docs/testing.md, "Which tests run on both series").
pytestmark = pytest.mark.one_series

# Values chosen to hit every check: hostile numbers (negative, huge, non-finite, float32
# overflow), malformed lists, odd tokens. A command line is either valid (it renders a 16- or
# 24-px image with one sample) or, two times in three, valid but for one hostile token (the
# renders are the time; the hostile tokens the point), so that both outcomes are met often
# (the last test checks that: 15 renders and 25 refusals of 40, derandomized).
VALID = {
    "--shader": ["osl", "nodes", "principled"],
    "--grid": ["1x1", "2x1", "1X2"],
    "--size": ["16", "24"],
    "--hdri-strength": ["1", "0", "2.5"],
    "--hdri-rotation": ["-1e-05", "370", "-90"],
    "--sun-dir": ["-0.45,-0.55,0.70", "0,0,-1", "1e200,0,0", "-1,-1,-1"],
    "--sun-strength": ["0", "3"],
    "--albedo": ["1,0.5,0", "0,0,0"],
    "--env-samples": ["1", "2"],
    "--seed": ["0", "7"],
    "--view": ["D", "normal", "full"],
    "--g": ["smith_ggx_correlated"],
    "--units": ["unity"],
    "--diffuse": ["lambert"],
}
HOSTILE = [
    "-1",
    "1e39",
    "nan",
    "inf",
    "-inf",
    "1e309",
    "abc",
    "",
    "0x10",
    "1,2",
    "0,0,0",
    "2147483648",
    "-7",
    "1,2,3,4",
    "--out",
    "16.5",
    "0x3",
    "-1x2",
    "99999",
    "16x16",
    "beckmann",
    "arnold",
]
REQUIRED = ("--shader", "--grid", "--size")
OPTIONAL = tuple(f for f in VALID if f not in REQUIRED)
OUTCOMES = []


@st.composite
def command_lines(draw):
    flags = list(REQUIRED) + draw(st.lists(st.sampled_from(OPTIONAL), max_size=3, unique=True))
    values = [draw(st.sampled_from(VALID[f])) for f in flags]
    if draw(st.integers(0, 2)):  # one hostile token, two times in three
        k = draw(st.integers(0, len(flags) - 1))
        values[k] = draw(st.sampled_from(HOSTILE))
    argv = ["render", "--samples", "1"]
    for flag, value in zip(flags, values):
        argv += [flag, value] if draw(st.booleans()) else [f"{flag}={value}"]
    if draw(st.booleans()):
        argv.append(draw(st.sampled_from(["--pixel-centres", "--env-visibility"])))
    return argv


def _listing(root: Path) -> set:
    return set(root.rglob("*"))


@settings(
    max_examples=40,
    deadline=None,
    derandomize=True,
    database=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture],
)
@given(argv=command_lines())
def test_fuzzed_command_lines_exit_0_or_2_with_one_line(argv, tmp_path_factory, capsys):
    work = tmp_path_factory.mktemp("fuzz")
    out = work / "out"
    before = _listing(work)
    code = cli.main(argv + ["--out", str(out)])
    OUTCOMES.append(code)
    err = capsys.readouterr().err
    assert code in (0, 2), (argv, code, err)
    assert "Traceback" not in err, (argv, err)
    if code == 2:
        lines = [line for line in err.splitlines() if line.strip()]
        assert len(lines) == 1 and lines[0].startswith("ctlab: error: "), (argv, err)
    stray = {p for p in _listing(work) - before if out not in p.parents and p != out}
    assert not stray, (argv, stray)


def test_the_fuzzer_reached_both_outcomes():
    """The generator is worth its name only if many command lines render and many fail."""
    if not OUTCOMES:
        pytest.skip("runs after the fuzzer test, in the same session")
    assert OUTCOMES.count(0) >= 10 and OUTCOMES.count(2) >= 15, (len(OUTCOMES), OUTCOMES)
