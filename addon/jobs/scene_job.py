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
``principled_seed/``) and the CIEDE2000 of its mean colour (``what_numbers_mean``).

One kind of reference in both modes: Principled's Multiscatter GGX where the model's energy is
compensated, its GGX where it is none (blender/convert.py ``ENERGY_OF``; with ``--convert`` the
conversion follows the file's distribution, and ``--energy`` sets the reference's).

The .blend is opened, changed in memory only and never saved. Everything is checked before
anything is written (bad input: one line, exit status 2, nothing written); every output is
written whole (core.files).
"""

from __future__ import annotations

import html
import json
import os
from dataclasses import dataclass, field
from pathlib import Path

import bpy
import numpy as np

from ..blender import convert, light_sync, model_node, node_group, osl_shader, renderer
from ..core.compare import ciede2000, heatmap, metrics, read_image, srgb_to_lab, write_png
from ..core.errors import UserError
from ..core.files import (
    atomic_path,
    check_writable,
    forget_report,
    json_text,
    refuse_overwrite,
    write_json,
    write_text,
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
    REC709_LUMINANCE,
    scene_transport_problem,
)
from ..core.report import STYLE
from .pipeline import Events

RENDER_FILES = renderer.OUTPUT_FILES + ("layers.exr",)
OUTPUT_FILES = ("metrics.json", "diff.png", "materials.png", "report.html")
DISTRIBUTIONS = ("auto", "GGX", "MULTI_GGX")
HEATMAP_MAX = 10.0
MAX_SIZE = 16384
MAX_SEED = 2**31 - 1
# The first bytes of a .blend: plain, gzip (before 3.0) or zstd (3.0 and later) compressed.
BLEND_MAGIC = (b"BLENDER", b"\x1f\x8b", b"\x28\xb5\x2f\xfd")
# Colours of the compared materials in materials.png (others grey, the world black).
PALETTE = (
    (0.90, 0.30, 0.25),
    (0.25, 0.60, 0.95),
    (0.35, 0.80, 0.35),
    (0.95, 0.75, 0.20),
    (0.70, 0.40, 0.85),
    (0.20, 0.80, 0.80),
    (0.95, 0.50, 0.70),
    (0.60, 0.45, 0.25),
)
OTHER_GREY = 0.35


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
# Input checks (before anything is written)


def check_blend_file(path: Path) -> Path:
    """An existing, readable Blender file (by its first bytes, not its name)."""
    path = Path(path)
    if not path.exists():
        raise UserError(f"no such file: {path}; give a .blend file")
    if not path.is_file():
        raise UserError(f"{path} is not a file; give a .blend file")
    try:
        with open(path, "rb") as f:
            head = f.read(7)
    except OSError as exc:
        raise UserError(f"cannot read {path} ({exc.strerror or exc})") from None
    if not any(head.startswith(m) for m in BLEND_MAGIC):
        raise UserError(f"{path} is not a Blender file (.blend); give one saved by Blender")
    return path.resolve()


def open_blend(path: Path, log) -> bpy.types.Scene:
    """Open the file (scripts not run, never saved); its active scene."""
    try:
        with renderer.quiet(log):
            bpy.ops.wm.open_mainfile(filepath=str(path), load_ui=False, use_scripts=False)
    except RuntimeError as exc:
        reason = str(exc).strip().splitlines()
        raise UserError(
            f"Blender cannot open {path}: {reason[-1] if reason else 'unknown error'}"
        ) from None
    scene = bpy.context.scene
    if scene is None:
        raise UserError(f"{path} has no scene")
    return scene


def choose_camera(scene: bpy.types.Scene, name: str | None) -> bpy.types.Object:
    cameras = sorted(o.name for o in scene.objects if o.type == 'CAMERA')
    listed = f"; its cameras: {', '.join(cameras)}" if cameras else "; it has no camera object"
    if name is not None:
        obj = scene.objects.get(name)
        if obj is None or obj.type != 'CAMERA':
            raise UserError(f"scene {scene.name!r} has no camera named {name!r}{listed}")
        return obj
    if scene.camera is None or scene.camera.type != 'CAMERA':
        raise UserError(
            f"scene {scene.name!r} has no active camera{listed}; set one in the "
            "file or name one with --camera"
        )
    return scene.camera


def image_files(image: bpy.types.Image) -> list:
    """The files an image reads (one per UDIM tile), absolute."""
    path = bpy.path.abspath(image.filepath, library=image.library)
    if image.source == 'TILED' and "<UDIM>" in path:
        return [path.replace("<UDIM>", str(t.number)) for t in image.tiles]
    return [path]


def check_data(path: Path) -> list:
    """Linked libraries and missing image files are refused; returns the image files read."""
    if len(bpy.data.libraries):
        names = ", ".join(lib.name for lib in bpy.data.libraries)
        raise UserError(
            f"{path.name} links data from other files ({names}); make it local "
            "(File > External Data, or Object > Relations > Make Local) and save "
            "a copy"
        )
    files = []
    ours = node_group.table_images()  # the model's tables and bakes: made again when it syncs
    for image in bpy.data.images:
        if image.users == 0 or image.source not in ('FILE', 'SEQUENCE', 'MOVIE', 'TILED'):
            continue
        if image.packed_file is not None or len(getattr(image, "packed_files", ())):
            continue
        if image in ours:
            continue
        for f in image_files(image):
            if not f or not os.path.isfile(f):
                raise UserError(
                    f"image {image.name!r} of {path.name}: its file is missing "
                    f"({f or 'no path'}); find it (File > External Data > Find "
                    "Missing Files) or pack it, and save"
                )
            files.append(f)
    return files


def scene_materials(scene: bpy.types.Scene) -> list:
    """The materials on the scene's objects that render, in name order."""
    found = set()
    for obj in scene.objects:
        if obj.hide_render:
            continue
        for slot in obj.material_slots:
            if slot.material is not None:
                found.add(slot.material)
    return sorted(found, key=lambda m: m.name)


# ---------------------------------------------------------------------------------------
# The model's side


def refresh_osl(nodes) -> None:
    """A file saved with another version of the shader gets this version's (in memory):
    the text datablock refreshed and each script node recompiled, keeping its values."""
    current = osl_shader.source()
    stale = [
        n
        for n in nodes
        if model_node.implementation(n) == "osl" and n.script.as_string() != current
    ]
    for node in stale:
        osl_shader.compile_script_node(node)


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
# Rendering


def image_size(scene: bpy.types.Scene, size: int) -> tuple:
    """(width, height) with ``size`` the longer side and the camera's displayed aspect."""
    r = scene.render
    aspect = (r.resolution_x * r.pixel_aspect_x) / max(r.resolution_y * r.pixel_aspect_y, 1e-9)
    if aspect >= 1:
        return size, max(1, round(size / aspect))
    return max(1, round(size * aspect)), size


def configure(scene: bpy.types.Scene, camera, job: SceneJob, osl: bool) -> tuple:
    """Cycles on the CPU, the same for both renders: the job's samples and seed, no denoiser,
    no adaptive sampling, exact path tracing (renderer.set_exact_path_tracing), OSL when a
    model node needs it; the file's light paths, filter and colour management are kept.
    Only the active view layer renders, with the Material Index pass; no compositor."""
    width, height = image_size(scene, job.size)
    r = scene.render
    r.engine = 'CYCLES'
    r.resolution_x, r.resolution_y = width, height
    r.resolution_percentage = 100
    r.pixel_aspect_x = r.pixel_aspect_y = 1.0
    r.use_border = False
    r.use_compositing = False
    r.use_sequencer = False
    r.use_single_layer = True
    r.use_persistent_data = False
    scene.camera = camera
    cy = scene.cycles
    cy.device = 'CPU'
    cy.shading_system = osl
    cy.samples = job.samples
    cy.seed = job.seed
    cy.use_animated_seed = False
    cy.use_denoising = False
    cy.use_adaptive_sampling = False
    if hasattr(cy, "time_limit"):
        cy.time_limit = 0.0
    renderer.set_exact_path_tracing(scene)
    layer = bpy.context.view_layer
    layer.use_pass_material_index = True
    if layer.material_override is not None:
        job.notes.append(f"view layer material override {layer.material_override.name!r} cleared")
        layer.material_override = None
    return width, height


def save_layers(scene: bpy.types.Scene, image, path: Path) -> None:
    """The Render Result as Blender's multilayer EXR (Combined, Material Index), whole."""
    s = scene.render.image_settings
    if hasattr(s, "media_type"):  # 5.0 and later
        s.media_type = 'MULTI_LAYER_IMAGE'
    s.file_format = 'OPEN_EXR_MULTILAYER'
    s.color_depth = '32'
    s.exr_codec = 'ZIP'
    try:
        with atomic_path(path) as tmp:
            image.save_render(str(tmp), scene=scene)
    finally:
        if hasattr(s, "media_type"):
            s.media_type = 'IMAGE'
        s.file_format = 'OPEN_EXR'


INDEX_CHANNELS = ("IndexMA.X", "Material Index.X")  # 4.5; 5.x


def read_material_index(path: Path) -> np.ndarray:
    """The Material Index pass of a multilayer EXR (all parts searched) as int (h, w)."""
    from ..core.hdri import oiio

    OIIO = oiio()
    inp = OIIO.ImageInput.open(str(path))
    if inp is None:
        raise UserError(f"cannot read {path}: {OIIO.geterror().strip()}")
    try:
        part = 0
        while inp.seek_subimage(part, 0):
            spec = inp.spec()
            for c, name in enumerate(spec.channelnames):
                if any(name == ch or name.endswith("." + ch) for ch in INDEX_CHANNELS):
                    px = inp.read_image(part, 0, c, c + 1, OIIO.FLOAT)
                    px = np.asarray(px, dtype=np.float32).reshape(spec.height, spec.width)
                    return np.rint(px).astype(np.int32)
            part += 1
    finally:
        inp.close()
    raise UserError(f"{path} holds no Material Index pass; Blender did not render it")


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


def render_into(scene, folder: Path, description: dict, log) -> tuple:
    """Render, write render.exr, render.png, scene.json and layers.exr; (description, index)."""
    description = renderer.render(scene, folder, description, log)
    result = bpy.data.images.get("Render Result")
    with renderer.quiet(log):
        save_layers(scene, result, folder / "layers.exr")
    return description, read_material_index(folder / "layers.exr")


# ---------------------------------------------------------------------------------------
# Measuring and writing


def _luminance(img: np.ndarray, mask: np.ndarray):
    if not mask.any():
        return None
    return float(np.mean(img[mask].astype(np.float64) @ np.array(REC709_LUMINANCE)))


def measure(lin_m, disp_m, lin_p, disp_p, de, mask) -> dict:
    """compare.metrics (model as A, Principled as B) and the luminance ratio model/Principled
    over a mask; None where the mask is empty."""
    y_m, y_p = _luminance(lin_m, mask), _luminance(lin_p, mask)
    out = {
        "pixels": int(mask.sum()),
        "luminance_model": y_m,
        "luminance_principled": y_p,
        "luminance_ratio": (y_m / y_p) if y_m is not None and y_p else None,
    }
    if mask.any():
        out.update(metrics(lin_m, lin_p, disp_m, disp_p, de, mask))
    else:
        out.update(
            {
                k: None
                for k in (
                    "mae",
                    "rmse",
                    "rel_luminance_error",
                    "psnr_db",
                    "ciede2000_mean",
                    "ciede2000_p95",
                )
            }
        )
    return out


def what_numbers_mean(lin_p, lin_p2, disp_m, disp_p, de_noise, mask) -> dict:
    """Beside the per-pixel mean CIEDE2000, what a reader needs to weigh it: the noise floor,
    the same measures between Principled and Principled rendered again with another seed
    (the same scene, so all of it is Monte Carlo noise), and the CIEDE2000 of the mask's
    mean displayed colours, model against Principled (noise averages out of a mean, not out
    of the per-pixel mean: a pixel's noise adds to its difference)."""
    if not mask.any():
        return dict.fromkeys(
            ("noise_floor_ciede2000_mean", "noise_floor_luminance_ratio", "ciede2000_of_mean")
        )
    mean_m, mean_p = (np.mean(d[mask][:, :3].astype(np.float64), axis=0) for d in (disp_m, disp_p))
    y_p, y_p2 = _luminance(lin_p, mask), _luminance(lin_p2, mask)
    lab_m, lab_p = (srgb_to_lab(c.reshape(1, 1, 3)) for c in (mean_m, mean_p))
    return {
        "noise_floor_ciede2000_mean": float(np.mean(de_noise[mask])),
        "noise_floor_luminance_ratio": (y_p2 / y_p) if y_p else None,
        "ciede2000_of_mean": float(ciede2000(lab_m, lab_p).ravel()[0]),
    }


def mask_image(index: np.ndarray, entries: list) -> np.ndarray:
    """materials.png: each compared material in its palette colour, other materials grey,
    the world (index 0) black."""
    img = np.where((index > 0)[..., None], OTHER_GREY, 0.0) * np.ones(3)
    for e in entries:
        img[index == e["pass_index"]] = e["mask_colour"]
    return img


def _fmt(value, fmt: str) -> str:
    return "&ndash;" if value is None else format(value, fmt)


def write_scene_report(out: Path, data: dict) -> Path:
    """report.html: model | Principled | difference, the mask map and the material table."""
    model_label = "Cook-Torrance" + (" (converted)" if data["convert"] else "")
    principled_label = "Principled BSDF" + (" (the file's)" if data["convert"] else " (converted)")
    figs = (
        ("model/render.png", model_label),
        ("principled/render.png", principled_label),
        ("diff.png", f"&Delta;E00 (black 0, white &ge; {HEATMAP_MAX:g})"),
        ("materials.png", "materials compared (colours below; grey: the others)"),
    )
    row = "".join(
        f"<figure><img src='{src}' alt='{html.escape(src)}'><figcaption>"
        f"{label if label.startswith('&') else html.escape(label)}</figcaption>"
        "</figure>"
        for src, label in figs
    )
    head = (
        "<tr><th></th><th>material</th><th>model</th><th>Principled</th><th>pixels</th>"
        "<th>&Delta;E00 mean</th><th>noise floor &Delta;E00 mean</th>"
        "<th>&Delta;E00 of the mean colour</th><th>&Delta;E00 p95</th><th>luminance model / "
        "Principled</th><th>PSNR (dB)</th><th>notes</th></tr>"
    )
    rows = []
    for e in data["materials"]:
        swatch = "#%02x%02x%02x" % tuple(round(255 * c) for c in e["mask_colour"])
        model = e["model"]
        what = (
            f"{model['implementation']}, G {model['g_model']}, {model['diffuse_model']}, "
            f"energy {model['energy']}, {model['light_transport']}"
        )
        rows.append(
            f"<tr><td style='background:{swatch}'></td><td>{html.escape(e['name'])}</td>"
            f"<td>{html.escape(what)}</td>"
            f"<td>{html.escape(str(e.get('principled_distribution') or ''))}</td>"
            f"<td>{e['pixels']}</td><td>{_fmt(e['ciede2000_mean'], '.2f')}</td>"
            f"<td>{_fmt(e.get('noise_floor_ciede2000_mean'), '.2f')}</td>"
            f"<td>{_fmt(e.get('ciede2000_of_mean'), '.2f')}</td>"
            f"<td>{_fmt(e['ciede2000_p95'], '.2f')}</td>"
            f"<td>{_fmt(e['luminance_ratio'], '.4f')}</td><td>{_fmt(e['psnr_db'], '.2f')}</td>"
            f"<td>{html.escape('; '.join(e['notes']))}</td></tr>"
        )
    o = data["overall"]
    rows.append(
        f"<tr class='all'><td></td><td colspan=3>all compared materials</td>"
        f"<td>{o['pixels']}</td><td>{_fmt(o['ciede2000_mean'], '.2f')}</td><td></td><td></td>"
        f"<td>{_fmt(o['ciede2000_p95'], '.2f')}</td>"
        f"<td>{_fmt(o['luminance_ratio'], '.4f')}</td>"
        f"<td>{_fmt(o['psnr_db'], '.2f')}</td><td></td></tr>"
    )
    params = {
        k: data[k]
        for k in (
            "blend",
            "scene",
            "camera",
            "width",
            "height",
            "samples",
            "seed",
            "light_transport",
            "convert",
            "osl",
            "view_transform",
            "blender",
            "notes",
        )
    }
    direction = (
        "the file's Principled BSDF materials converted to the Cook-Torrance model, "
        "against the originals"
        if data["convert"]
        else "the file's Cook-Torrance materials against each converted to Principled BSDF"
    )
    outside = data["outside"]
    scene, blend = html.escape(data["scene"]), html.escape(Path(data["blend"]).name)
    page = f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>Cook-Torrance Lab: scene {scene}</title>
{STYLE}<style>figure img {{ width: 360px; max-width: 100%; }}</style></head><body>
<h1>Cook-Torrance Lab: {blend}, scene “{scene}”</h1>
<p>The scene through its camera {html.escape(data['camera'])}, rendered twice with the same
Cycles settings ({data['width']}&times;{data['height']} px, {data['samples']} samples, seed
{data['seed']}, light transport <b>{data['light_transport']}</b>): {direction}. Each
material's pixels are those of its Material Index; &Delta;E00 (CIEDE2000) compares the displayed
colours (render.png, the file's view transform {html.escape(data['view_transform'])}), the
luminance ratio the mean Rec. 709 luminance of the raw values (render.exr). The per-pixel mean
&Delta;E00 includes each pixel's noise: the <i>noise floor</i> is the same mean between
Principled and Principled rendered again with another seed (all of it noise), and the
&Delta;E00 of the mean colour compares each material's mean displayed colour, from which noise
averages out. The two compared renders share their seed, so their noise is partly the same
and cancels: a per-pixel mean below the noise floor is usual. Both sides use the same kind of
Principled: Multiscatter GGX where the model's
energy is compensated, GGX where it is none.</p>
<div class='row'>{row}</div>
<h2>Per material</h2><table>{head}{''.join(rows)}</table>
<p>Elsewhere in the image (other materials and the world, which see the compared materials in
the scene transport): mean &Delta;E00 {_fmt(outside['ciede2000_mean'], '.2f')} over
{outside['pixels']} pixels. Render times: model {data['render_seconds']['model']:.1f} s,
Principled {data['render_seconds']['principled']:.1f} s.</p>
<h2>Parameters</h2><pre>{html.escape(json.dumps(params, indent=2))}</pre>
</body></html>
"""
    path = Path(out) / "report.html"
    write_text(path, page)
    return path


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
    width, height = configure(scene, camera, job, osl)

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
