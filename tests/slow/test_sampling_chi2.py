"""Chi-square goodness-of-fit tests of the reference integrator's samplers (osl/cook_torrance.osl)
against the densities it divides by, on the OSL code itself: tests/osl/sampling_probe.osl draws
one sample per pixel from uniform numbers the test supplies (float images, read exactly at the
pixels' texels: test_the_probe_reads_its_inputs_exactly), and evaluates the densities at the
evaluation points of tests/chi2.py, one 1024 x 1024 render each. Every run has 1024^2 samples;
the runs that must pass share a Sidak-corrected level (chi2.sidak), and the mutants (a density
10% too large, the GGX density with the wrong Jacobian, the environment density with its
rotation reversed, the environment sampler and density both with the other Blender's texture
rows) must fail at that level, which shows that the test can fail.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from pathlib import Path

import bpy
import numpy as np
import pytest

import chi2
from helpers import ROOT
from addon.blender import compat, osl_shader, pixel_grid, renderer
from addon.core.env_importance import tables_for
from addon.core.hdri import write_float_exr

# The samplers' distributions: the same on every Blender series, so run on one
# (docs/testing.md, "Which tests run on both series").
pytestmark = pytest.mark.one_series

PROBE = ROOT / "tests" / "osl" / "sampling_probe.osl"
SIZE = 1024  # the renders: SIZE x SIZE pixels
assert (chi2.EVAL_ROWS, chi2.EVAL_COLS) == (SIZE, SIZE)


def _unit(*v):
    v = np.asarray(v, dtype=np.float64)
    return v / np.linalg.norm(v)


N_UP = _unit(0.35, -0.55, 0.76)  # tilted, z > 0
N_DOWN = _unit(-0.6, 0.25, -0.55)  # tilted, z < 0: make_frame's other branch


def _view(n, incidence_deg):
    """A direction at incidence_deg from n (toward the viewer)."""
    t = np.cross(n, (0.0, 0.0, 1.0))
    t /= np.linalg.norm(t)
    a = math.radians(incidence_deg)
    return math.cos(a) * n + math.sin(a) * t


@dataclass(frozen=True)
class Run:
    """One sampler configuration. kind: "brdf" (sample_brdf / brdf_pdf), "env" (env_sample /
    env_pdf), "mis" (half the samples each; (brdf_pdf + env_pdf) / 2) or "vndf"
    (sample_ggx_visible / ggx_visible_pdf)."""

    kind: str
    seed: int
    alpha: float = 0.5
    incidence: float = 0.0
    p_spec: float = 1.0
    normal: tuple = tuple(N_UP)
    rotation: float = 1.0  # the HDRI's rotation (radians), env and mis

    @property
    def view(self):
        return _view(np.asarray(self.normal), self.incidence)


RUNS = {
    "ggx a=0.1 30deg": Run("brdf", 1, alpha=0.1, incidence=30.0),
    "ggx a=0.5 70deg": Run("brdf", 2, alpha=0.5, incidence=70.0),
    "ggx a=1.0 0deg": Run("brdf", 3, alpha=1.0, incidence=0.0),
    "cosine": Run("brdf", 4, alpha=0.5, incidence=40.0, p_spec=0.0, normal=tuple(N_DOWN)),
    "mixture a=0.3 45deg": Run(
        "brdf", 5, alpha=0.3, incidence=45.0, p_spec=0.5, normal=tuple(N_DOWN)
    ),
    "environment": Run("env", 6),
    "mis": Run("mis", 7, alpha=0.3, incidence=50.0, p_spec=0.5),
    "visible a=0.5 70deg": Run("vndf", 8, alpha=0.5, incidence=70.0),
    "visible a=0.3 80deg": Run("vndf", 9, alpha=0.3, incidence=80.0, normal=tuple(N_DOWN)),
}
LEVEL = chi2.sidak(len(RUNS))  # each run's p-value must exceed this


def _sky(height=128, width=256):
    """A smooth synthetic HDRI: a sky gradient (bright toward +Z, dim below) and a soft
    bright blob, in Blender's lat-long mapping (row 0 the top)."""
    t = (np.arange(height) + 0.5) / height
    s = (np.arange(width) + 0.5) / width
    elev = (0.5 - t)[:, None] * np.pi
    phi = (0.5 - s)[None, :] * 2 * np.pi
    d = np.stack(
        [np.cos(elev) * np.cos(phi), np.cos(elev) * np.sin(phi), np.sin(elev) * np.ones_like(phi)],
        axis=-1,
    )
    sky = 0.3 + 0.7 * (0.5 + 0.5 * d[..., 2])
    blob = 40.0 * np.exp((d @ _unit(0.5, 0.6, 0.62) - 1.0) / 0.02)  # 1/e at 11 deg
    rgb = (sky + blob)[..., None] * np.array([0.8, 0.9, 1.1])
    return rgb.astype(np.float32)


class Probe:
    """The probe shader on a SIZE x SIZE pixel grid, in a fresh empty scene."""

    def __init__(self, hdri: Path):
        bpy.ops.wm.read_factory_settings(use_empty=True)
        self.scene = bpy.context.scene
        plane = pixel_grid.build(self.scene, SIZE, SIZE)
        mat = bpy.data.materials.new("Cook-Torrance Lab Sampling Probe")
        compat.use_nodes(mat)
        tree = mat.node_tree
        for node in list(tree.nodes):
            tree.nodes.remove(node)
        self.node = tree.nodes.new("ShaderNodeScript")
        osl_shader.compile_script_node(self.node, path=PROBE, name="ctlab_sampling_probe.osl")
        out = tree.nodes.new("ShaderNodeOutputMaterial")
        tree.links.new(self.node.outputs["BSDF"], out.inputs["Surface"])
        self.textures = {}
        for name in ("rand_u", "rand_w", "dir_in"):
            color = pixel_grid.image_input(
                tree, pixel_grid.data_image(f"ctlab_{name}", np.zeros((1, 1, 3)))
            )
            tree.links.new(color, osl_shader.socket(self.node, name))
            self.textures[name] = color.node
        plane.data.materials.append(mat)
        tables = tables_for(hdri)
        self.set(
            env_marginal=tables["marginal"],
            env_conditional=tables["conditional"],
            env_pdf_table=tables["pdf"],
        )
        renderer.configure(self.scene, "osl", "D", 1, pixel_centres=True)

    def set(self, **params):
        for key, value in params.items():
            if key in self.textures:
                self.textures[key].image = pixel_grid.data_image(f"ctlab_{key}", value)
            else:
                osl_shader.socket(self.node, key).default_value = value

    def render(self, mode: str, run: Run | None = None, **params) -> np.ndarray:
        if run is not None:
            params = (
                dict(
                    n_in=tuple(run.normal),
                    v_in=tuple(run.view),
                    alpha=run.alpha,
                    p_spec=run.p_spec,
                    rotation=run.rotation,
                    tex_bottom_up=int(compat.osl_texture_rows_bottom_up()),
                )
                | params
            )
        self.set(mode=mode, **params)
        return pixel_grid.render(self.scene, os.devnull).astype(np.float64)


@dataclass
class Samples:
    dirs: np.ndarray  # (SIZE, SIZE, 3); 0 where invalid
    valid: np.ndarray
    rand: dict = field(default_factory=dict)  # the uniform numbers the draw used

    @property
    def observed(self):
        return chi2.histogram(self.dirs, self.valid)


class Lab:
    """The probe, the HDRI, and each run's samples and densities, made once."""

    def __init__(self, hdri: Path):
        self.probe = Probe(hdri)
        self.eval_dirs, self.weights = chi2.evaluation_directions()
        self._samples, self._pdfs = {}, {}

    def samples(self, name: str) -> Samples:
        if name not in self._samples:
            run = RUNS[name]
            rng = np.random.default_rng(run.seed)
            rand_u = chi2.uniform(rng, (SIZE, SIZE, 3))
            rand_w = chi2.uniform(rng, (SIZE, SIZE, 3))
            rand_w[..., 2] = 0.0
            rand_w[SIZE // 2 :, :, 2] = 1.0  # mis: the lower half of the rows samples the env
            dirs = self.probe.render(f"{run.kind}_sample", run, rand_u=rand_u, rand_w=rand_w)
            valid = np.any(dirs != 0.0, axis=-1)
            self._samples[name] = Samples(dirs, valid, {"rand_u": rand_u, "rand_w": rand_w})
        return self._samples[name]

    def pdf(self, name: str, mode: str | None = None, **params) -> np.ndarray:
        """The run's density (or another mode's) at the evaluation points."""
        key = (name, mode, tuple(sorted(params.items())))
        if key not in self._pdfs:
            run = RUNS[name]
            self._pdfs[key] = self.probe.render(
                mode or f"{run.kind}_pdf", run, dir_in=self.eval_dirs, **params
            )[..., 0]
        return self._pdfs[key]

    def expected(self, pdf: np.ndarray) -> np.ndarray:
        return chi2.integrate(pdf, self.weights) * SIZE * SIZE

    def test(self, name: str, pdf: np.ndarray | None = None) -> chi2.Chi2Result:
        s = self.samples(name)
        pdf = self.pdf(name) if pdf is None else pdf
        return chi2.chi2_test(s.observed, self.expected(pdf), SIZE * SIZE)


@pytest.fixture(scope="module")
def lab(tmp_path_factory):
    hdri = tmp_path_factory.mktemp("chi2") / "sky.exr"
    write_float_exr(hdri, _sky())
    return Lab(hdri)


# The density's integral over the sphere must be the fraction of valid samples within
# INTEGRAL_SIGMAS binomial standard errors of that fraction, plus INTEGRAL_SLACK for the
# integration (chi2.integrate against a numpy copy of brdf_pdf on an 8192 x 8192 grid: off by
# at most 4e-5, in the grazing GGX run, where the horizon cuts the lobe; the environment's
# density integrates exactly, chi2._row_layout).
INTEGRAL_SIGMAS = 4.0
INTEGRAL_SLACK = 1e-4


def _check(lab: Lab, name: str) -> chi2.Chi2Result:
    result = lab.test(name)
    print(f"{name}: {result}")
    assert result.p_value > LEVEL, f"{name}: the samples do not follow the density: {result}"
    assert (
        abs(result.integral - result.valid_fraction)
        <= INTEGRAL_SIGMAS * result.valid_stderr + INTEGRAL_SLACK
    ), (
        f"{name}: the density integrates to {result.integral:.5f}, not to the valid "
        f"fraction {result.valid_fraction:.5f}: {result}"
    )
    return result


# ---------------------------------------------------------------------------------------
# The harness itself (no render)
def test_chi2_survival_function_matches_closed_forms():
    """Q(k/2, x/2) against closed forms: exp(-x/2) for 2 dof, erfc(sqrt(x/2)) for 1, and
    exp(-x/2)(1 + x/2) for 4; and the normal limit for a large dof (both branches of the
    incomplete gamma). Catches a wrong series or continued fraction."""
    for x in (0.01, 0.5, 1.0, 2.0, 3.5, 10.0, 40.0, 200.0):
        assert chi2.chi2_sf(x, 2) == pytest.approx(math.exp(-x / 2), rel=1e-10, abs=1e-300)
        assert chi2.chi2_sf(x, 1) == pytest.approx(
            math.erfc(math.sqrt(x / 2)), rel=1e-9, abs=1e-300
        )
        assert chi2.chi2_sf(x, 4) == pytest.approx(
            math.exp(-x / 2) * (1 + x / 2), rel=1e-10, abs=1e-300
        )
    # Wilson-Hilferty: (X/k)^(1/3) is nearly normal, mean 1 - 2/(9k), variance 2/(9k)
    k = 6000
    for z in (-2.0, 0.0, 2.0, 3.0):
        x = k * (1 - 2 / (9 * k) + z * math.sqrt(2 / (9 * k))) ** 3
        assert chi2.chi2_sf(x, k) == pytest.approx(0.5 * math.erfc(z / math.sqrt(2)), abs=2e-4)
    assert chi2.sidak(1) == pytest.approx(0.01)
    assert chi2.sidak(7) == pytest.approx(1 - 0.99 ** (1 / 7))


def test_chi2_harness_on_numpy_draws():
    """The harness on an exact sampler (uniform directions, numpy) passes, and on the same
    draws against a density 10% off fails; the evaluation points' weights integrate a
    constant exactly. Catches a wrong cell mapping, weighting or pooling."""
    _, weights = chi2.evaluation_directions()
    assert weights.sum() == pytest.approx(4 * np.pi, rel=1e-12)
    rng = np.random.default_rng(0)
    n = 1 << 20
    z = 2 * rng.random(n) - 1
    phi = 2 * np.pi * rng.random(n)
    r = np.sqrt(1 - z * z)
    dirs = np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=-1)
    # the samples below z = -0.5 (a cell edge) "invalid", as samples below a surface: the
    # density is 1/(4 pi) above and 0 below, and integrates to the valid fraction 3/4
    valid = dirs[:, 2] > -0.5
    eval_dirs, _ = chi2.evaluation_directions()
    pdf = np.where(eval_dirs[..., 2] > -0.5, 1 / (4 * np.pi), 0.0)
    observed = chi2.histogram(dirs, valid)
    exact = chi2.chi2_test(observed, chi2.integrate(pdf, weights) * n, n)
    assert exact.p_value > 0.01, exact
    assert exact.integral == pytest.approx(0.75, rel=1e-12)
    assert abs(exact.valid_fraction - 0.75) < 4 * exact.valid_stderr
    off = chi2.chi2_test(observed, chi2.integrate(pdf, weights) * n * 1.1, n)
    assert off.p_value < 1e-6, off


# ---------------------------------------------------------------------------------------
# The probe


def test_the_probe_reads_its_inputs_exactly(lab):
    """Per-pixel numbers (here in [-1, 1), as directions are) reach the shader and come back
    in the render bit for bit: an Image Texture read at each pixel's centre in OSL mode (on
    5.2 texture() is bilinear, so a pixel centre must be a texel centre), and a negative
    emission kept. Catches a render or texture lookup that perturbs them, which would make the
    probe's samples not those of the numbers the test drew."""
    values = 2.0 * chi2.uniform(np.random.default_rng(99), (SIZE, SIZE, 3)) - 1.0
    echo = lab.probe.render("echo", rand_u=values)
    assert np.array_equal(echo, values.astype(np.float64)), (
        f"max error {np.abs(echo - values).max():.3g}"
    )


# ---------------------------------------------------------------------------------------
# The samplers: each must pass at the Sidak level, and its density integrate to its valid
# fraction


@pytest.mark.parametrize("name", ["ggx a=0.1 30deg", "ggx a=0.5 70deg", "ggx a=1.0 0deg"])
def test_ggx_lobe_follows_its_pdf(lab, name):
    """sample_brdf with p_spec = 1 (sample_ggx_half, reflected) against brdf_pdf = D (n.h) /
    (4 (v.h)), a narrow, a grazing and a broad lobe about a tilted normal (alpha = 1 at normal
    incidence: uniform over the hemisphere, from a non-uniform h). Catches a wrong
    half-vector inversion (tan^2), a wrong Jacobian, a frame (make_frame) that is not
    orthonormal or not about n, and invalid (below-surface) draws that the pdf claims."""
    _check(lab, name)


def test_cosine_lobe_follows_its_pdf(lab):
    """sample_brdf with p_spec = 0 (sample_cosine) against (n.l)/pi, about a normal pointing
    down (z < 0: make_frame's other branch). Catches a wrong disk mapping (sqrt(u1)) or
    frame."""
    _check(lab, "cosine")


def test_brdf_mixture_follows_its_pdf(lab):
    """sample_brdf with p_spec = 0.5 (u_pick chooses the lobe) against the mixture brdf_pdf,
    about a downward normal. Catches a lobe choice that does not match the weights the pdf
    gives the lobes."""
    _check(lab, "mixture a=0.3 45deg")


def test_environment_sampler_follows_its_pdf(lab):
    """env_sample on the tables of a smooth synthetic sky (a gradient and a soft blob), rotated,
    against env_pdf; and the density env_sample returns is env_pdf at its draw. Catches tables
    read at the wrong rows (the 5.2 bottom-up convention), a rotation applied the wrong way in
    one of the two, a missing cos(elevation) Jacobian, and a sampler whose returned density is
    not the one its pdf function gives."""
    _check(lab, "environment")
    s = lab.samples("environment")
    out = lab.probe.render("env_sample_pdf", RUNS["environment"], **s.rand)
    returned, looked_up, valid = out[..., 0], out[..., 1], out[..., 2] > 0.5
    assert np.array_equal(valid, s.valid)
    rel = np.abs(returned - looked_up) / np.maximum(returned, 1e-30)
    # A draw within float rounding of its tile's edge (u3 or u4 within 1e-3 of 0 or 1) may
    # come back, through its direction, in the neighbouring tile; every other draw agrees.
    u3, u4 = s.rand["rand_u"][..., 2], s.rand["rand_w"][..., 0]
    at_edge = np.minimum(np.minimum(u3, 1 - u3), np.minimum(u4, 1 - u4)) < 1e-3
    off = valid & (rel > 1e-4)
    print(
        f"returned pdf != env_pdf at {off.sum()} draws, {(off & at_edge).sum()} of them at "
        f"a tile's edge"
    )
    assert not (off & ~at_edge).any(), (
        f"{(off & ~at_edge).sum()} draws away from tiles' edges: returned pdf != env_pdf "
        f"(worst rel {rel[valid & ~at_edge].max():.3g})"
    )


def test_mis_mixture_follows_the_balance_heuristic_density(lab):
    """Half the samples from sample_brdf and half from env_sample against (brdf_pdf +
    env_pdf) / 2: the one-sample density the integrator's 1 / (p_brdf + p_env) weights assume.
    Catches an env_pdf or brdf_pdf inconsistent with its sampler in the combination (the
    weights would then not sum to one)."""
    _check(lab, "mis")


@pytest.mark.parametrize("name", ["visible a=0.5 70deg", "visible a=0.3 80deg"])
def test_ggx_visible_normals_follow_their_pdf(lab, name):
    """sample_ggx_visible (Heitz 2018; the scene transport's correction draws with it) against
    ggx_visible_pdf = G1(v) D(h) / (4 (n.v)), at grazing views, about an upward and a
    downward normal. Catches a wrong stretch or hemisphere split, a missing G1 (the density
    would not integrate to the valid fraction) and draws the pdf does not claim."""
    _check(lab, name)


# ---------------------------------------------------------------------------------------
# Mutants: the same samples against a wrong density must fail


def test_mutant_pdf_10_percent_too_large_fails(lab):
    """The grazing GGX lobe's samples against 1.1 x brdf_pdf: rejected at the Sidak level (and
    its integral is off the valid fraction). Shows that the test can fail."""
    name = "ggx a=0.5 70deg"
    result = lab.test(name, 1.1 * lab.pdf(name))
    print(f"mutant 1.1 x pdf: {result}")
    assert result.p_value < LEVEL, result
    assert (
        abs(result.integral - result.valid_fraction)
        > INTEGRAL_SIGMAS * result.valid_stderr + INTEGRAL_SLACK
    )


def test_mutant_ggx_jacobian_fails(lab):
    """The grazing GGX lobe's samples against D (n.h) / (4 (n.h)), (n.h) where the reflection
    Jacobian's (v.h) belongs, rescaled to integrate to the valid fraction (so only its shape is
    wrong): rejected at the Sidak level."""
    name = "ggx a=0.5 70deg"
    mutant = lab.pdf(name, "brdf_pdf_nh")
    s = lab.samples(name)
    mutant = mutant * (s.valid.mean() / (chi2.integrate(mutant, lab.weights).sum()))
    result = lab.test(name, mutant)
    print(f"mutant (n.h) for (v.h): {result}")
    assert result.p_value < LEVEL, result


def test_mutant_visible_normals_against_the_d_nh_density_fails(lab):
    """The visible normals' grazing samples against the D (n.h) sampler's density (brdf_pdf,
    p_spec = 1), rescaled to integrate to the valid fraction (so only its shape differs):
    rejected at the Sidak level. The two samplers differ; the test tells them apart."""
    name = "visible a=0.5 70deg"
    mutant = lab.pdf(name, "brdf_pdf", p_spec=1.0)
    s = lab.samples(name)
    mutant = mutant * (s.valid.mean() / (chi2.integrate(mutant, lab.weights).sum()))
    result = lab.test(name, mutant)
    print(f"mutant D (n.h) density for visible normals: {result}")
    assert result.p_value < LEVEL, result


def test_mutant_env_rotation_reversed_fails(lab):
    """The environment's samples against env_pdf with the rotation reversed (the sampler's
    rotation and the pdf's disagreeing): rejected at the Sidak level."""
    name = "environment"
    result = lab.test(name, lab.pdf(name, rotation=-RUNS[name].rotation))
    print(f"mutant rotation reversed: {result}")
    assert result.p_value < LEVEL, result


def test_mutant_other_versions_row_convention_fails(lab):
    """env_sample and env_pdf both reading the tables with the other Blender's texture-row
    convention (tex_bottom_up flipped: rows counted from the wrong end, as the shader would on
    5.2 without compat.osl_texture_rows_bottom_up): the draw takes a row from the marginal but
    its column from the mirrored row's conditional, and claims the mirrored row's density.
    Rejected at the Sidak level: a convention error cannot pass as consistent."""
    run = RUNS["environment"]
    wrong = 1 - int(compat.osl_texture_rows_bottom_up())
    rng = np.random.default_rng(run.seed)
    rand = {
        "rand_u": chi2.uniform(rng, (SIZE, SIZE, 3)),
        "rand_w": chi2.uniform(rng, (SIZE, SIZE, 3)),
    }
    dirs = lab.probe.render("env_sample", run, tex_bottom_up=wrong, **rand)
    pdf = lab.probe.render("env_pdf", run, tex_bottom_up=wrong, dir_in=lab.eval_dirs)[..., 0]
    observed = chi2.histogram(dirs, np.any(dirs != 0.0, axis=-1))
    result = chi2.chi2_test(observed, lab.expected(pdf), SIZE * SIZE)
    print(f"mutant row convention flipped: {result}")
    assert result.p_value < LEVEL, result
