"""``ctlab scene FILE.blend``: a user's own scene rendered through its camera twice and compared,
material by material.

- Without ``--convert``: the scene's Cook-Torrance materials (those whose node tree holds the
  model node) against each of them converted to Principled BSDF (blender/convert.py).
- With ``--convert``: the scene's Principled materials converted to Cook-Torrance against the
  originals (the reference).

Both renders use the same Cycles settings (CPU, the same samples and seed, no denoiser, no
adaptive sampling, exact path tracing: no clamping, no glossy filter, reflective caustics;
OSL on for both when an OSL model node is in the scene) and the file's camera, light paths and
colour management. Each material gets a unique pass index; the Material Index pass of the
first render (Blender's multilayer EXR of the Render Result, ``layers.exr``, read with the
bundled OpenImageIO) says which pixels are whose. Per material: the mean CIEDE2000 of the
displayed colours and the ratio of the mean Rec. 709 luminance of the raw values (model /
Principled), and more, in metrics.json; a CIEDE2000 heat map (diff.png), a map of the masks
(materials.png) and report.html. Beside the per-pixel mean CIEDE2000, each material's noise
floor (Principled against Principled rendered again with another seed, into
``principled_seed/``) and the CIEDE2000 of its mean colour (core/compare.py
``what_numbers_mean``).

One kind of reference in both modes: Principled's Multiscatter GGX where the model's energy is
compensated, its GGX where it is none (blender/convert.py ``ENERGY_OF``; with ``--convert`` the
conversion follows the file's distribution, and ``--energy`` sets the reference's).

This module runs the job: the file is opened and checked by blender/user_blend.py, both
renders set up by blender/comparison_render.py, measured by core/compare.py and reported by
core/scene_report.py. The .blend is opened, changed in memory only and never saved.
Everything is checked before anything is written (bad input: one line, exit status 2, nothing
written); every output is written whole (core.files).
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from pathlib import Path

import bpy
import numpy as np

from ..blender import convert, light_sync, model_node, renderer
from ..blender.comparison_render import RENDER_FILES, render_into, set_comparison_render
from ..blender.user_blend import (
    check_blend_file,
    check_data,
    choose_camera,
    open_blend,
    refresh_osl,
    scene_materials,
)
from ..core.compare import (
    PALETTE,
    ciede2000,
    heatmap,
    mask_image,
    measure,
    read_image,
    srgb_to_lab,
    what_numbers_mean,
    write_png,
)
from ..core.errors import UserError
from ..core.files import (
    check_writable,
    forget_report,
    json_text,
    refuse_overwrite,
    write_json,
)
from ..core.model import (
    ARTIST,
    DEFAULT_TRANSPORT,
    DIFFUSE_MODELS,
    ENERGY_MODES,
    G_MODELS,
    IMPLEMENTATIONS,
    LIGHT_TRANSPORTS,
    MAX_SAMPLES,
    scene_transport_problem,
)
from ..core.scene_report import write_scene_report
from .pipeline import Events

OUTPUT_FILES = ("metrics.json", "diff.png", "materials.png", "report.html")
DISTRIBUTIONS = ("auto", "GGX", "MULTI_GGX")
HEATMAP_MAX = 10.0
MAX_SIZE = 16384
MAX_SEED = 2**31 - 1


@dataclass
class SceneJob:
    """The command's settings, validated by ``check``. None: keep what the file has."""

    blend: Path
    out: Path
    convert: bool = False
    light_transport: str = DEFAULT_TRANSPORT[ARTIST]
    shader: str | None = None  # osl | nodes (with --convert: default osl)
    g_model: str | None = None
    diffuse_model: str | None = None
    energy: str | None = None
    size: int = 256
    samples: int = 64
    seed: int = 0
    camera: str | None = None
    principled_distribution: str | None = None  # auto | GGX | MULTI_GGX
    verbose: bool = False
    notes: list = field(default_factory=list)

    def check(self) -> None:
        choices = (
            ("--light-transport", self.light_transport, LIGHT_TRANSPORTS),
            ("--shader", self.shader, IMPLEMENTATIONS),
            ("--g", self.g_model, G_MODELS),
            ("--diffuse", self.diffuse_model, DIFFUSE_MODELS),
            ("--energy", self.energy, ENERGY_MODES),
            ("--principled-distribution", self.principled_distribution, DISTRIBUTIONS),
        )
        for flag, value, values in choices:
            if value is not None and value not in values:
                raise UserError(f"unknown {flag} {value!r}; choose one of: {', '.join(values)}")
        for flag, value, lo, hi in (
            ("--size", self.size, 1, MAX_SIZE),
            ("--samples", self.samples, 1, MAX_SAMPLES),
            ("--seed", self.seed, 0, MAX_SEED),
        ):
            if not lo <= value <= hi:
                raise UserError(f"{flag} {value} out of range; use {lo} to {hi}")
        if self.convert and self.principled_distribution not in (None, "auto"):
            raise UserError(
                "--principled-distribution sets the Principled conversion of the "
                "model materials; with --convert the file's own Principled "
                "materials are the reference: leave it out"
            )


# ---------------------------------------------------------------------------------------
# The model's side


def set_model(mat: bpy.types.Material, job: SceneJob, impl: str | None) -> bpy.types.Node:
    """The compared model material as the job wants it: implementation, full view, the light
    transport and the switches given on the command line."""
    node = model_node.find(mat)
    if impl is not None and model_node.implementation(node) != impl:
        node = model_node.replace_node(mat.node_tree, node, impl)
    refresh_osl([node])
    model_node.set_option(node, "view", "full")
    model_node.set_option(node, "light_transport", job.light_transport)
    for key, value in (
        ("g_model", job.g_model),
        ("diffuse_model", job.diffuse_model),
        ("energy", job.energy),
    ):
        if value is not None:
            model_node.set_option(node, key, value)
    problem = scene_transport_problem(model_node.get_option(node, "units"), job.light_transport)
    if problem:
        raise UserError(f"material {mat.name!r}: {problem}")
    return node


def model_description(mat, node) -> dict:
    d = {"implementation": model_node.implementation(node)}
    d.update(
        {
            key: model_node.get_option(node, key)
            for key in ("g_model", "diffuse_model", "energy", "units", "light_transport")
        }
    )
    return d


def distribution_for(job: SceneJob, energy: str) -> str:
    """Principled's GGX for a converted model material: single-scatter GGX is the model's
    own lobe (single scattering); Multiscatter GGX for the energy-compensated model."""
    choice = job.principled_distribution or "auto"
    if choice != "auto":
        return choice
    return "MULTI_GGX" if energy == "compensated" else "GGX"


def to_principled(mat, job: SceneJob, energy: str) -> dict:
    notes = convert.model_to_principled(mat)
    bsdf = convert.surface_principled(mat)
    distribution = distribution_for(job, energy)
    if bsdf is not None:
        bsdf.distribution = distribution
    return {"principled_distribution": distribution, "notes": notes}


# ---------------------------------------------------------------------------------------
# The noise floor


NOISE_FOLDER = "principled_seed"  # Principled again, another seed: the noise floor


def render_noise_floor(scene, job: SceneJob, folder: Path, description: dict, log, events, step):
    """Principled rendered again with the next seed (the one before, at the last seed) into
    ``folder``: what two renders of the same scene differ by (``what_numbers_mean``)."""
    events.progress(step, 4, "Principled again with another seed (the noise floor)")
    seed = job.seed + 1 if job.seed < MAX_SEED else job.seed - 1
    scene.cycles.seed = seed
    try:
        d = renderer.render(scene, folder, dict(description, side="principled", seed=seed), log)
    finally:
        scene.cycles.seed = job.seed
    events.note(f"{d['render_seconds']:.1f} s")
    events.check()


# ---------------------------------------------------------------------------------------
# The job


def run_scene(job: SceneJob, events: Events | None = None) -> dict:
    """Open the file, check it, render both versions into OUT/model and OUT/principled,
    compare per material, write metrics.json, diff.png, materials.png and report.html.
    Returns metrics.json's data (with "report")."""
    events = events or Events()
    job.check()
    blend = check_blend_file(job.blend)
    log = None if job.verbose else os.devnull
    scene = open_blend(blend, log)
    camera = choose_camera(scene, job.camera)
    inputs = [blend] + check_data(blend)
    used = scene_materials(scene)

    # The compared materials, and the side each starts on.
    if job.convert:
        targets = [m for m in used if convert.surface_principled(m) is not None]
        if not targets:
            raise UserError(
                f"scene {scene.name!r} has no Principled BSDF material on its "
                "objects; nothing to convert"
            )
    else:
        targets = [m for m in used if model_node.find(m) is not None]
        if not targets:
            raise UserError(
                f"scene {scene.name!r} has no Cook-Torrance material on its "
                "objects; use --convert to compare its Principled materials"
            )
    for i, mat in enumerate(bpy.data.materials):  # unique, in memory only
        mat.pass_index = i + 1

    # Every model material in the scene follows the scene's world and lights (light_sync).
    env = light_sync.Environment(scene)
    others = [m for m in used if model_node.find(m) is not None and m not in targets]
    refresh_osl([model_node.find(m) for m in others])
    entries = []
    for k, mat in enumerate(targets):
        entries.append(
            {
                "name": mat.name,
                "pass_index": mat.pass_index,
                "mask_colour": PALETTE[k % len(PALETTE)],
                "notes": [],
            }
        )
    if job.convert and job.energy is not None:
        # one kind of reference in both modes: Principled's GGX as the model's energy
        # (convert.DISTRIBUTION_OF), as distribution_for does the other way
        wanted = convert.DISTRIBUTION_OF[job.energy]
        for mat, e in zip(targets, entries):
            bsdf = convert.surface_principled(mat)
            if bsdf.distribution != wanted:
                e["notes"].append(
                    f"reference: {bsdf.distribution} rendered as {wanted} (--energy {job.energy})"
                )
                bsdf.distribution = wanted
    if not job.convert:
        for mat, e in zip(targets, entries):
            node = set_model(mat, job, job.shader)
            light_sync.sync_material(mat, scene, env=env)
            e["model"] = model_description(mat, node)
    for mat in others:
        light_sync.sync_material(mat, scene, env=env)

    impl = job.shader or "osl"
    osl = any(
        model_node.implementation(model_node.find(m)) == "osl"
        for m in used
        if model_node.find(m) is not None
    ) or (job.convert and impl == "osl")
    width, height = set_comparison_render(
        scene, camera, job.size, job.samples, job.seed, osl, job.notes
    )

    out = Path(job.out)
    folders = {
        "model": out / "model",
        "principled": out / "principled",
        "noise": out / NOISE_FOLDER,
    }
    refuse_overwrite(
        inputs,
        [f / n for f in folders.values() for n in RENDER_FILES] + [out / n for n in OUTPUT_FILES],
        [out],
    )  # and not in the cache
    check_writable(out)
    forget_report(out / "report.html")  # no old report beside new images; only ctlab's

    description = {
        "blend": str(blend),
        "scene": scene.name,
        "camera": camera.name,
        "width": width,
        "height": height,
        "seed": job.seed,
        "light_transport": job.light_transport,
        "convert": job.convert,
        "osl": osl,
    }
    first, second = ("principled", "model") if job.convert else ("model", "principled")
    scenes = {}
    events.check()
    events.progress(1, 4, f"{first}: {width}x{height} px, {job.samples} samples")
    scenes[first], index = render_into(scene, folders[first], dict(description, side=first), log)
    events.note(f"{scenes[first]['render_seconds']:.1f} s")
    events.check()
    if first == "principled":
        render_noise_floor(scene, job, folders["noise"], description, log, events, 2)

    # The other side: each compared material converted.
    if job.convert:
        for mat, e in zip(targets, entries):
            e["principled_distribution"] = convert.surface_principled(mat).distribution
            e["notes"] += convert.principled_to_model(mat, scene, impl)
            e["model"] = model_description(mat, set_model(mat, job, None))
            light_sync.sync_material(mat, scene, env=env)
    else:
        for mat, e in zip(targets, entries):
            e.update(to_principled(mat, job, e["model"]["energy"]))

    step = 3 if first == "principled" else 2
    events.progress(step, 4, f"{second}: {width}x{height} px, {job.samples} samples")
    scenes[second], index2 = render_into(
        scene, folders[second], dict(description, side=second), log
    )
    events.note(f"{scenes[second]['render_seconds']:.1f} s")
    events.check()
    if second == "principled":
        render_noise_floor(scene, job, folders["noise"], description, log, events, 3)

    events.progress(
        4, 4, "comparing; writing metrics.json, diff.png, materials.png and report.html"
    )
    lin_m, disp_m = (read_image(folders["model"] / n) for n in ("render.exr", "render.png"))
    lin_p, disp_p = (read_image(folders["principled"] / n) for n in ("render.exr", "render.png"))
    lin_p2, disp_p2 = (read_image(folders["noise"] / n) for n in ("render.exr", "render.png"))
    de = ciede2000(srgb_to_lab(disp_m), srgb_to_lab(disp_p))
    de_noise = ciede2000(srgb_to_lab(disp_p2), srgb_to_lab(disp_p))
    compared = np.zeros(index.shape, dtype=bool)
    for e in entries:
        mask = index == e["pass_index"]
        compared |= mask
        e.update(measure(lin_m, disp_m, lin_p, disp_p, de, mask))
        e.update(what_numbers_mean(lin_p, lin_p2, disp_m, disp_p, de_noise, mask))
    data = dict(
        description,
        samples=job.samples,
        view_transform=scene.view_settings.view_transform,
        blender=bpy.app.version_string,
        notes=job.notes,
        render_seconds={k: v["render_seconds"] for k, v in scenes.items()},
        masks_agree=float(np.mean(index == index2)),
        heatmap_max_ciede2000=HEATMAP_MAX,
        materials=entries,
        overall=measure(lin_m, disp_m, lin_p, disp_p, de, compared),
        outside=measure(lin_m, disp_m, lin_p, disp_p, de, ~compared),
        image=measure(lin_m, disp_m, lin_p, disp_p, de, np.ones_like(compared)),
    )
    data["materials"] = [dict(e, mask_colour=list(e["mask_colour"])) for e in entries]
    write_png(out / "diff.png", heatmap(de, HEATMAP_MAX))
    write_png(out / "materials.png", mask_image(index, entries))
    write_json(out / "metrics.json", data)
    data = json.loads(json_text(data))
    data["report"] = str(write_scene_report(out, data))
    return data
