"""The pipeline: rendering views of the sphere matrix, what the main comparison job and the
Principled-parity job render and compare (run as task graphs by jobs/graph.py) and the bake
(the BRDF plots: jobs/plot_job.py), as functions that take validated settings
(core.settings) and report through ``Events``. The command line, the background job, the
benchmark and the tests all run these; none of them parses another's output.

A job reports ``progress(step, total, message)`` before each step and ``note(message)`` within
one, and polls ``cancelled()`` between steps: when it answers True the job stops with
``Cancelled``, keeping every output it finished (each render folder is written whole).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path
from collections.abc import Callable

import bpy

from ..blender import model_node, renderer, scene_builder
from ..blender.paths import bundled_hdri, resolve_hdri
from ..core import energy, ibl_bake
from ..core.errors import Cancelled, UserError
from ..core.hdri import load_hdri
from ..core.files import check_writable, forget_report, refuse_overwrite
from ..core.gate import Gate
from ..core.model import BAKED_IBL_MODES, DEFAULT_TRANSPORT, LAB
from ..core.paths import safe_name
from ..core.settings import (
    MIN_SPHERE_PX,
    SIZE_RANGE,
    MatrixSettings,
    with_overrides,
    world_to_pixel,
)


def _nothing(*_args) -> None:
    return None


@dataclass
class Events:
    progress: Callable = _nothing  # (step, total, message), before each step
    note: Callable = _nothing  # (message), within a step
    cancelled: Callable = lambda: False  # polled between steps
    warn: Callable = _nothing  # (message), something left alone or repaired

    def check(self) -> None:
        if self.cancelled():
            raise Cancelled()

    def bake_progress(self, fraction: float, message: str) -> None:
        self.note(f"bake {100 * fraction:3.0f}%: {message}")


# ----------------------------------------------------------------------------------------
# Renders


def render_views(
    settings: MatrixSettings,
    out_dirs: dict,
    samples: int,
    *,
    pixel_centres: bool = False,
    engine: str = "cycles",
    verbose: bool = False,
    events: Events | None = None,
    on_view=None,
) -> dict:
    """Build the matrix once in a fresh empty scene and render each view into its folder
    (``{view: folder}``); the shader compiles once. ``on_view(i, view, description)`` follows
    each render. Returns the last scene description. ``pixel_centres``: every view as one
    sample at each pixel centre (no anti-aliasing)."""
    events = events or Events()
    for out_dir in out_dirs.values():
        refuse_overwrite(
            job_inputs(settings),
            [Path(out_dir) / name for name in renderer.OUTPUT_FILES],
            [out_dir],
        )
        check_writable(out_dir)
    files = scene_builder.environment_files(settings, events.bake_progress)
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    description = scene_builder.build_matrix(scene, settings, files)
    node = next(
        filter(None, (model_node.find(m) for m in bpy.data.materials if m.get(scene_builder.TAG))),
        None,
    )
    log = None if verbose else os.devnull  # Blender's own per-tile lines
    for i, (view, out_dir) in enumerate(out_dirs.items()):
        events.check()
        model = settings.model_options(view=view)
        description["model"] = model.as_dict()
        if node is not None:
            model_node.set_options(node, model)
        renderer.configure(
            scene,
            settings.shader,
            view,
            samples,
            model.seed,
            pixel_centres,
            engine,
            path_traced=settings.shader != "principled" and model.path_traced(),
        )
        description = renderer.render(scene, out_dir, description, log)
        if on_view:
            on_view(i, view, description)
    return description


def job_inputs(settings: MatrixSettings) -> list:
    """The files a render reads that a user gave (its HDRI, its lights file, its textures)."""
    return [
        resolve_hdri(settings.hdri),
        settings.lights_file or None,
        settings.albedo_texture or None,
        settings.normal_map or None,
    ]


def refuse_job_outputs(settings: MatrixSettings, out: Path, folders, names=()) -> None:
    """Before a job's first render: its inputs are none of the files it will write in its
    render folders (and ``names`` in ``out``), and none of those is blocked or in the cache
    (core.paths.check_job)."""
    out = Path(out)
    refuse_overwrite(
        job_inputs(settings),
        [out / f / n for f in folders for n in renderer.OUTPUT_FILES] + [out / n for n in names],
        [out],
    )


def render_one(settings: MatrixSettings, out_dir: Path, samples: int, **kw) -> dict:
    """Build the matrix in a fresh empty scene and render its view into out_dir."""
    return render_views(settings, {settings.model.view: Path(out_dir)}, samples, **kw)


# ----------------------------------------------------------------------------------------
# The main job

SMITH = {"g_model": "smith_ggx_correlated"}
# The matrix job's renders: (folder, label, shader, IBL mode, settings changed from the
# base's). The last six are the attribution's (``ATTRIBUTION_PREFIX``): the seed model and
# Principled again, then each switch, rendered smaller (``attribution_size``).
MATRIX_RENDERS = (
    ("cook_torrance", "Cook-Torrance (OSL, reference IBL)", "osl", "reference", {}),
    ("principled", "Principled BSDF", "principled", "reference", {}),
    ("split_sum", "Cook-Torrance (OSL, split-sum IBL)", "osl", "split_sum", {}),
    ("unity", "Cook-Torrance (OSL, Unity IBL)", "osl", "unity", {}),
    (
        "split_sum_corrected",
        "Cook-Torrance (OSL, split-sum toward the dominant direction)",
        "osl",
        "split_sum_corrected",
        {},
    ),
    ("nodes", "Cook-Torrance (node group, split-sum IBL)", "nodes", "split_sum", {}),
    ("attr_seed", "Cook-Torrance (OSL, reference IBL; attribution)", "osl", "reference", {}),
    ("attr_principled", "Principled BSDF (attribution)", "principled", "reference", {}),
    ("attr_smith", "Cook-Torrance with Smith G", "osl", "reference", SMITH),
    (
        "attr_smith_lambert",
        "Cook-Torrance with Smith G and Lambert diffuse",
        "osl",
        "reference",
        dict(SMITH, diffuse_model="lambert"),
    ),
    (
        "attr_principled_ggx",
        "Principled BSDF (single-scatter GGX)",
        "principled",
        "reference",
        {"principled_distribution": "GGX"},
    ),
    (
        "attr_compensated",
        "Cook-Torrance with Smith G, Lambert diffuse and energy compensation",
        "osl",
        "reference",
        dict(SMITH, diffuse_model="lambert", energy="compensated"),
    ),
)
# Its comparisons: (folder, render, against). The model against Principled; the baked IBL
# modes against the reference integration (the accuracy study of the split-sum); the node
# group against the OSL shader in the same mode (parity); the attribution's steps.
MATRIX_COMPARISONS = (
    ("compare", "cook_torrance", "principled"),
    ("compare_split_sum", "split_sum", "cook_torrance"),
    ("compare_unity", "unity", "cook_torrance"),
    ("compare_split_sum_corrected", "split_sum_corrected", "cook_torrance"),
    ("compare_nodes", "nodes", "split_sum"),
    ("compare_attr_seed", "attr_seed", "attr_principled"),
    ("compare_attr_smith", "attr_smith", "attr_principled"),
    ("compare_attr_smith_lambert", "attr_smith_lambert", "attr_principled"),
    ("compare_attr_ggx", "attr_smith_lambert", "attr_principled_ggx"),
    ("compare_attr_compensated", "attr_compensated", "attr_principled"),
)
# The attribution: the error against Principled after each switch (comparison folder, the
# switch; the step it follows, where not the one before).
ATTRIBUTION = (
    ("compare_attr_seed", "seed model"),
    ("compare_attr_smith", "G: Cook-Torrance to Smith"),
    ("compare_attr_smith_lambert", "diffuse: Disney to Lambert"),
    ("compare_attr_ggx", "Principled: multiscatter to single-scatter GGX"),
    (
        "compare_attr_compensated",
        "or instead the model: energy compensated (against multiscatter Principled)",
        2,
    ),
)
# The white furnace (core/energy.py): (folder, G model, energy).
FURNACE_RENDERS = (
    ("furnace_cook_torrance", "cook_torrance", "none"),
    ("furnace_smith", "smith_ggx_correlated", "none"),
    ("furnace_smith_compensated", "smith_ggx_correlated", "compensated"),
)


def furnace_label(g_model: str, energy_mode: str) -> str:
    return f"{g_model} G" + (", compensated" if energy_mode != "none" else "")


def _forget_report(out: Path) -> None:
    """A job writes its report last: remove an earlier run's first, so that a job stopped
    half-way leaves no report showing new images beside old numbers."""
    forget_report(Path(out) / "report.html")  # only one ctlab wrote (core.files)


ATTRIBUTION_PREFIX = "attr_"
# 3/8: a seventh of the pixels. Measured against 1/2 (main job, 5.2.3, 7x7 at 512 px): each
# step's mean CIEDE2000 moved by at most 0.021 and each step's change by at most 0.005 (G
# 0.067 / 0.063, diffuse 0.044 / 0.040, multiscatter -0.809 / -0.805), the job 26 s shorter.
ATTRIBUTION_SCALE = 0.375


def attribution_size(base: MatrixSettings) -> dict:
    """The attribution's image size: 3/8 of the main render's (a seventh of its pixels),
    but its spheres at least MIN_SPHERE_PX across their radius and its sides at least the
    smallest image size (SIZE_RANGE). Its figures are per-sphere means of per-pixel
    differences at the same samples per pixel, so they keep their meaning on fewer pixels;
    all its steps, the seed model and Principled included, share the size."""
    radius_px = base.radius * world_to_pixel(base, (0.0, 0.0, 0.0))[1]
    least = max(MIN_SPHERE_PX / radius_px, SIZE_RANGE[0] / min(base.width, base.height))
    scale = min(1.0, max(ATTRIBUTION_SCALE, least))
    return {"width": math.ceil(base.width * scale), "height": math.ceil(base.height * scale)}


def matrix_settings(base: MatrixSettings) -> dict:
    """The main job's renders: folder -> settings, all validated before anything renders."""
    settings = {}
    for folder, _, shader, ibl, overrides in MATRIX_RENDERS:
        if folder.startswith(ATTRIBUTION_PREFIX):
            overrides = dict(overrides, **attribution_size(base))
        # the baked modes are the lab transport's approximations of the reference: with
        # --light-transport scene they stay lab renders (the study of the split-sum, and the
        # node group's parity with the OSL shader in the same mode)
        transport = (
            DEFAULT_TRANSPORT[LAB]
            if shader != "principled" and ibl in BAKED_IBL_MODES
            else base.model.light_transport
        )
        settings[folder] = with_overrides(
            base, dict(overrides, shader=shader, ibl=ibl, view="full", light_transport=transport)
        )
    for folder, g_model, energy_mode in FURNACE_RENDERS:
        settings[folder] = energy.furnace_settings(
            g_model, base.model.env_samples, base.model.seed, energy_mode
        )
    return settings


# ----------------------------------------------------------------------------------------
# The Principled-parity job

PARITY_HDRIS = ("forest", "studio")
PARITY_BOUND = 1.0  # every sphere's mean CIEDE2000
# (lab: the scene transport's closures for Smith and Lambert are Cycles' own GGX, so parity
# would hold without testing the model's integration)
PARITY_MODEL = dict(
    light_transport=DEFAULT_TRANSPORT[LAB],
    g_model="smith_ggx_correlated",
    diffuse_model="lambert",
    metallic=1.0,
    sun_strength=0.0,
    mutual_shadows=False,
)


def parity_hdris(names: str) -> list:
    """Blender's bundled HDRIs named in a comma list."""
    from ..blender.paths import BUNDLED_HDRIS

    chosen = [n.strip() for n in names.split(",") if n.strip()]
    if not chosen or any(n not in BUNDLED_HDRIS for n in chosen):
        raise UserError(
            f"unknown bundled HDRI in --parity-hdris {names!r}; choose from: "
            + ", ".join(BUNDLED_HDRIS)
        )
    return [bundled_hdri(n) for n in chosen]


def parity_runs(base: MatrixSettings, hdris: list, name: str | None = None) -> list:
    """(name, Cook-Torrance settings, Principled settings) per HDRI (jobs/graph.py's
    run_parity)."""
    jobs = []
    for hdri in hdris:
        ct = with_overrides(
            base, dict(PARITY_MODEL, hdri=str(hdri), shader="osl", ibl="reference", view="full")
        )
        # with the model's energy compensated, against Principled's own multiple scattering
        multiple = base.model.energy == "compensated"
        pr = with_overrides(
            base,
            dict(
                PARITY_MODEL,
                hdri=str(hdri),
                shader="principled",
                ibl="reference",
                view="full",
                principled_distribution="MULTI_GGX" if multiple else "GGX",
            ),
        )
        # a folder name made from a file's name: made safe in one place (core.paths)
        run = safe_name(name, "lights") if name and len(hdris) == 1 else None
        jobs.append((run or safe_name(Path(hdri).stem, "hdri"), ct, pr))
    names = [run for run, *_ in jobs]
    if len(set(names)) < len(names):
        twice = sorted({n for n in names if names.count(n) > 1})
        raise UserError(
            f"two parity HDRIs would share the run folder {twice[0]!r} (named from their "
            "file names); rename one"
        )
    return jobs


# ----------------------------------------------------------------------------------------
# The bake


def run_bake(
    hdri: Path,
    out: Path | None = None,
    events: Events | None = None,
    warn=None,
    force: bool = False,
) -> Path:
    """Bake the split-sum files of an HDRI (cached by content hash); with ``out`` copy them
    there through its write gate (core.gate; ``force``: over files ctlab did not write).
    Returns the folder holding them."""
    events = events or Events()
    load_hdri(hdri)  # the HDRI checked before --out is made
    if out:
        Gate(out, "the bake's files", force=force).check(ibl_bake.file_names(), inputs=[hdri])
        check_writable(out)
    folder = ibl_bake.bake(Path(hdri), events.bake_progress, warn)
    if out:
        ibl_bake.export(folder, Path(out), source=hdri, force=force)
        folder = Path(out)
    return folder
