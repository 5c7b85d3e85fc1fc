"""One home per rule (core/model/rules.py, core/model/derived.py): every caller gets the model's
defaults and fallbacks from there, and the values there are the documented ones.

- No module of the add-on writes a light transport default, the node group's split-sum
  fallback, the samples limit or the smoothness -> alpha formula itself: a grep of the source
  finds none outside the rules (mutation: ``default="scene"`` put back into
  ui/operators/materials.py fails ``test_no_rule_written_outside_its_home``).
- The UI's EnumProperty defaults and the scene job's dataclass default are the rule's names
  (read from their syntax trees: the unit tier has no Blender).
- The rule's values: docs/model.md "Light transport" (lab for the matrix, the views and parity;
  scene for a material an artist adds or converts), the node group's baked modes, Unity's
  units refused in the scene transport with one message.
- The derived quantities agree with tests/reference_model.py's independent copy and with
  osl/ct_brdf.h's names and arguments.
"""

import ast
import re

import numpy as np
import pytest

from helpers import ROOT

from addon.core.errors import UserError
from addon.core.model import (
    ARTIST,
    BAKED_IBL_MODES,
    DEFAULT_TRANSPORT,
    LAB,
    MAX_SAMPLES,
    MIN_ALPHA,
    SCENE_UNITS_PROBLEM,
    ModelOptions,
    diff_color_from_metallic,
    ggx_alpha,
    perceptual_roughness,
    resolve,
    spec_color_from_metallic,
)

ADDON = ROOT / "addon"
RULES = ADDON / "core" / "model" / "rules.py"
DERIVED = ADDON / "core" / "model" / "derived.py"

# A rule written outside its home, as it was written before it had one.
OFFENCES = {
    "a light transport default": re.compile(
        r"""(default\s*=\s*|light_transport\s*(:\s*str\s*)?=\s*)["'](lab|scene)["']"""
    ),
    "a light transport set by hand": re.compile(
        r"""set_option\([^)]*["']light_transport["']\s*,\s*["'](lab|scene)["']"""
    ),
    "the node group's split-sum set by hand": re.compile(
        r"""set_option\([^)]*["']ibl["']\s*,\s*["']split_sum["']"""
    ),
    "the samples limit": re.compile(r"\b65536\b"),
    "smoothness -> alpha": re.compile(r"max\(\s*pr\s*(\*\s*pr|\*\*\s*2)\s*,"),
}
# A literal that is not the rule: the largest image side a scene.json may declare.
NOT_THE_RULE = {("addon/core/compare.py", "the samples limit")}


def _offences():
    found = {}
    for path in sorted(ADDON.rglob("*.py")):
        if path in (RULES, DERIVED):
            continue
        rel = path.relative_to(ROOT).as_posix()
        for n, line in enumerate(path.read_text().splitlines(), 1):
            for what, pattern in OFFENCES.items():
                if pattern.search(line) and (rel, what) not in NOT_THE_RULE:
                    found.setdefault(rel, []).append(f"{rel}:{n}: {what}: {line.strip()}")
    return found


def test_no_rule_written_outside_its_home():
    found = _offences()
    stray = [line for lines in found.values() for line in lines]
    assert not stray, "\n".join(stray)


def _keyword_default(path, cls, prop):
    """The source of ``prop``'s ``default=`` in class ``cls`` (an annotation whose value is a
    call, bpy's EnumProperty), or of its dataclass default."""
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ClassDef) and node.name == cls:
            for item in node.body:
                if isinstance(item, ast.AnnAssign) and item.target.id == prop:
                    if isinstance(item.annotation, ast.Call):  # bpy: name: EnumProperty(...)
                        kw = {k.arg: k.value for k in item.annotation.keywords}
                        return ast.unparse(kw["default"])
                    return ast.unparse(item.value)
    raise AssertionError(f"{cls}.{prop} not found in {path}")


@pytest.mark.parametrize(
    "path, cls",
    [
        ("ui/operators/materials.py", "CTLAB_OT_new_material"),
        ("ui/operators/comparison.py", "CTLAB_OT_scene_comparison"),
        ("jobs/scene_job.py", "SceneJob"),
    ],
)
def test_artists_transport_default_is_the_rules(path, cls):
    """The UI's new material, the UI's scene comparison and the scene job default to the
    rule's transport for an artist's material."""
    assert _keyword_default(ADDON / path, cls, "light_transport") == "DEFAULT_TRANSPORT[ARTIST]"


def test_transport_defaults_per_context():
    """docs/model.md "Light transport": lab for the matrix, the views and parity; scene for
    a material an artist adds or converts."""
    assert DEFAULT_TRANSPORT == {LAB: "lab", ARTIST: "scene"}
    assert ModelOptions().light_transport == "lab"
    assert resolve("osl", {}, LAB)["light_transport"] == "lab"
    assert resolve("nodes", {}, ARTIST)["light_transport"] == "scene"
    assert resolve("osl", {"light_transport": "lab"}, ARTIST)["light_transport"] == "lab"
    assert resolve("osl", {"light_transport": None}, ARTIST)["light_transport"] == "scene"
    with pytest.raises(ValueError):
        resolve("osl", {}, "studio")


def test_osl_samples_per_shading_point_follow_the_transport():
    """The lab estimates the whole indirect light with 4 BRDF + 4 environment samples; the
    scene transport only its correction, inside Cycles' path tracing, with 1 + 1 (the bench
    measured the same error in about half the time). Asked-for samples are kept; the node
    group has no such input."""
    assert ModelOptions().env_samples == 4
    assert ModelOptions(light_transport="scene").env_samples == 1
    assert ModelOptions(light_transport="scene", env_samples=8).env_samples == 8
    assert ModelOptions(light_transport="lab", env_samples=2).env_samples == 2
    assert resolve("osl", {}, LAB)["env_samples"] == 4
    assert resolve("osl", {}, ARTIST)["env_samples"] == 1
    assert resolve("osl", {"light_transport": "lab"}, ARTIST)["env_samples"] == 4
    assert resolve("osl", {"env_samples": 16}, ARTIST)["env_samples"] == 16
    assert "env_samples" not in resolve("nodes", {}, ARTIST)
    with pytest.raises(UserError, match="unknown light transport"):
        ModelOptions(light_transport="studio")


def test_node_group_takes_the_split_sum():
    """The group has the baked modes only: the reference (or nothing) becomes the split-sum;
    the OSL shader keeps every mode and defaults to the reference; Principled has none."""
    assert resolve("nodes")["ibl"] == "split_sum"
    assert resolve("nodes", {"ibl": "reference"})["ibl"] == "split_sum"
    for mode in BAKED_IBL_MODES:
        assert resolve("nodes", {"ibl": mode})["ibl"] == mode
        assert resolve("osl", {"ibl": mode})["ibl"] == mode
    assert resolve("osl")["ibl"] == "reference"
    assert "ibl" not in resolve("principled")


def test_unity_units_refused_in_the_scene_transport_with_one_message():
    for make in (
        lambda: resolve("osl", {"units": "unity"}, ARTIST),
        lambda: resolve("nodes", {"units": "unity", "light_transport": "scene"}),
        lambda: ModelOptions(units="unity", light_transport="scene"),
    ):
        with pytest.raises(UserError) as e:
            make()
        assert str(e.value) == SCENE_UNITS_PROBLEM
    assert resolve("osl", {"units": "unity"}, LAB)["units"] == "unity"
    # the shader's own fallback is the same rule: path traced only in physical units
    osl = (ROOT / "osl" / "cook_torrance.osl").read_text()
    assert 'light_transport == "scene" && view == "full" && units == "physical"' in osl


def test_samples_limit():
    """Cycles' samples limit (its integrator's maximum, 1 << 16)."""
    assert MAX_SAMPLES == 1 << 16


def test_derived_quantities_match_the_reference_and_the_shader():
    """pr = 1 - clamp(s), alpha = max(pr^2, 0.002), specColor = mix(0.04, albedo, m),
    diffColor = 0.96 albedo (1 - m) (docs/model.md "Derived quantities"), against
    tests/reference_model.py's independent copy; and ct_brdf.h's ggx_alpha takes pr."""
    from reference_model import terms

    albedo = np.array([0.9, 0.5, 0.2])
    n = v = l = np.array([[0.0, 0.0, 1.0]])
    for s in (-0.5, 0.0, 0.3, 0.97, 1.0, 1.5):
        for m in (0.0, 0.4, 1.0):
            ref = terms(n, v, l, albedo, m, min(1.0, max(0.0, s)))
            assert ggx_alpha(perceptual_roughness(s)) == pytest.approx(float(ref["alpha"]))
            assert spec_color_from_metallic(albedo, m) == pytest.approx(ref["spec_color"][0])
            assert diff_color_from_metallic(albedo, m) == pytest.approx(albedo * 0.96 * (1 - m))
    assert ggx_alpha(0.0) == MIN_ALPHA == 0.002
    header = (ROOT / "osl" / "ct_brdf.h").read_text()
    assert "float ggx_alpha(float pr) { return max(pr * pr, 0.002); }" in header
    assert "float perceptual_roughness(float smoothness)" in header
