"""Rendering a scene headless (Cycles, or EEVEE for the node group) and writing render.exr,
render.png and scene.json.

- The EXR holds the raw float view values (RGB, 32-bit, scene-linear).
- The PNG is for people: Standard view transform for term views, AgX for lighting views.
- Term views are rendered at pixel centres with no filter jitter (a box filter of width 0.01
  puts every sample at the pixel centre), one sample: each pixel is one exact shading point.
- The three outputs are written to temporary names and renamed when all are whole
  (core.files.atomic_paths).
"""

from __future__ import annotations

import contextlib
import os
import sys
import time
from pathlib import Path

import bpy

from . import model_node
from .compat import eevee_engine_id
from ..core.errors import UserError
from ..core.files import atomic_paths, check_writable, json_text
from ..core.model import AGX_VIEWS, EXACT_VIEWS

OUTPUT_FILES = ("render.exr", "render.png", "scene.json")


ENGINES = ("cycles", "eevee")


def configure_eevee(scene: bpy.types.Scene, view: str, samples: int, pixel_centres: bool) -> None:
    """EEVEE for the node group (OSL cannot run there): term views (and every view with
    ``pixel_centres``) take one sample with a zero-width filter."""
    scene.render.engine = eevee_engine_id()
    exact = view in EXACT_VIEWS or pixel_centres
    scene.eevee.taa_render_samples = 1 if exact else samples
    scene.render.filter_size = 0.0 if exact else 1.5


PATH_BOUNCES = 12  # Blender's default light paths, for the path-traced renders


def configure(
    scene: bpy.types.Scene,
    shader: str,
    view: str,
    samples: int,
    seed: int = 0,
    pixel_centres: bool = False,
    engine: str = "cycles",
    path_traced: bool = False,
) -> None:
    """Cycles on the CPU; OSL for the Cook-Torrance shader; no denoiser, no adaptive sampling
    and no clamping, so renders converge to the integral they estimate. Term views (and every
    view with ``pixel_centres``) take one sample at each pixel centre. ``engine`` "eevee"
    renders the node group with EEVEE instead. ``path_traced``: the model's scene transport
    (Cycles path traces its closures, with the world sampled as a light)."""
    if engine == "eevee":
        if shader != "nodes":
            raise UserError(
                f"EEVEE cannot render the {shader!r} shader here; use --shader nodes "
                "(the OSL shader needs Cycles on the CPU)"
            )
        configure_eevee(scene, view, samples, pixel_centres)
        _view_transform(scene, view)
        return
    set_converging_cycles(scene, shader == "osl", samples, seed)
    cy = scene.cycles
    if shader != "principled" and (view in EXACT_VIEWS or pixel_centres):
        cy.samples = 1
        cy.pixel_filter_type = 'BOX'
        cy.filter_width = 0.01
    else:
        cy.samples = samples
        cy.pixel_filter_type = 'BLACKMAN_HARRIS'
        cy.filter_width = 1.5
    if shader != "principled":
        # the lab shader integrates the lighting itself; the scene transport is path traced
        cy.max_bounces = PATH_BOUNCES if path_traced else 0
    if scene.world is not None:
        scene.world.cycles.sampling_method = (
            'NONE' if not path_traced and _only_the_model(scene) else 'AUTOMATIC'
        )
    scene.render.film_transparent = False
    _view_transform(scene, view)


# The settings under which Cycles' path tracing converges to the integral of the closures:
# no clamping, no glossy filter (it blurs a glossy lobe seen after a diffuse or rough bounce)
# and reflective caustics traced (docs/model.md "Light transport").
EXACT_PATH_TRACING = {
    "sample_clamp_direct": 0.0,
    "sample_clamp_indirect": 0.0,
    "blur_glossy": 0.0,
    "caustics_reflective": True,
}


def set_exact_path_tracing(scene: bpy.types.Scene) -> None:
    for key, value in EXACT_PATH_TRACING.items():
        setattr(scene.cycles, key, value)


def set_converging_cycles(scene: bpy.types.Scene, osl: bool, samples: int, seed: int) -> None:
    """The one place Cook-Torrance Lab sets Cycles for a render of its own (the matrix, a
    scene comparison, the world bake): Cycles on the CPU, OSL on or off, ``samples`` with a
    fixed ``seed``, no denoiser, no adaptive sampling, no time limit, no persistent data,
    and exact path tracing, so a render converges to the integral it estimates and two
    renders draw the same random numbers. Callers set what is theirs (filter, bounces,
    resolution) after it."""
    scene.render.engine = 'CYCLES'
    scene.render.use_persistent_data = False
    cy = scene.cycles
    cy.device = 'CPU'
    cy.shading_system = osl
    cy.samples = samples
    cy.seed = seed
    cy.use_animated_seed = False
    cy.use_denoising = False
    cy.use_adaptive_sampling = False
    if hasattr(cy, "time_limit"):
        cy.time_limit = 0.0
    set_exact_path_tracing(scene)


def inexact_path_tracing(scene: bpy.types.Scene) -> list:
    """The scene's Cycles settings that keep a path-traced render from converging to the
    model (for the panel's warning): ``["Clamp Indirect 10", ...]``, empty when none."""
    names = {
        "sample_clamp_direct": "Clamp Direct",
        "sample_clamp_indirect": "Clamp Indirect",
        "blur_glossy": "Filter Glossy",
        "caustics_reflective": "Reflective Caustics off",
    }
    out = []
    for key, value in EXACT_PATH_TRACING.items():
        have = getattr(scene.cycles, key)
        if isinstance(value, bool):
            if bool(have) != value:
                out.append(names[key])
        elif have != value:
            out.append(f"{names[key]} {have:g}")
    return out


def _only_the_model(scene: bpy.types.Scene) -> bool:
    """Whether every material of the scene's objects is the model's. Those emit and have no
    BSDF, so nothing then samples the world as a light, and Cycles' importance map of the world
    (built at sync by evaluating the world shader: 1.0 s of an OSL render's 1.2 s sync on 5.2)
    can be left out. Any other material (Principled beside the model, in a user's scene)
    keeps it."""
    materials = {slot.material for obj in scene.objects for slot in obj.material_slots}
    return bool(materials) and all(
        m is not None and model_node.find(m) is not None for m in materials
    )


def _view_transform(scene: bpy.types.Scene, view: str) -> None:
    vs = scene.view_settings
    vs.view_transform = 'AgX' if view in AGX_VIEWS else 'Standard'
    vs.look = 'None'
    vs.exposure = 0.0
    vs.gamma = 1.0
    scene.display_settings.display_device = 'sRGB'


@contextlib.contextmanager
def quiet(log_path: Path | None, stderr: bool = False):
    """Send Blender's C-level stdout (per-tile progress lines) to a log file; with ``stderr``
    its stderr too (an image writer's own error line: the failed write is reported once, by
    the verified rename, core.files)."""
    if log_path is None:
        yield
        return
    sys.stdout.flush()
    fds = (1, 2) if stderr else (1,)
    saved = [os.dup(fd) for fd in fds]
    with open(log_path, "ab") as log:
        for fd in fds:
            os.dup2(log.fileno(), fd)
        try:
            yield
        finally:
            sys.stdout.flush()
            for fd, old in zip(fds, saved):
                os.dup2(old, fd)
                os.close(old)


def _save(scene, image, path: Path, fmt: str) -> None:
    settings = scene.render.image_settings
    if fmt == "exr":
        settings.file_format = 'OPEN_EXR'
        settings.color_mode = 'RGB'
        settings.color_depth = '32'
        settings.exr_codec = 'ZIP'
    else:
        settings.file_format = 'PNG'
        settings.color_mode = 'RGB'
        settings.color_depth = '8'
        settings.compression = 15
    image.save_render(str(path), scene=scene)


def save_exr(scene, image, path: Path) -> None:
    """Save a render result as a 32-bit float RGB EXR (the raw values)."""
    _save(scene, image, path, "exr")


def _seconds(stamp: str) -> float:
    """'MM:SS.ss' or 'HH:MM:SS.ss' (Cycles' metadata) to seconds."""
    total = 0.0
    for part in stamp.split(":"):
        total = total * 60 + float(part)
    return total


def cycles_times(exr_path: Path) -> dict:
    """Cycles' own synchronisation (scene and shader compile) and render times, from the
    metadata it writes into the image."""
    from ..core.hdri import oiio

    OIIO = oiio()
    inp = OIIO.ImageInput.open(str(exr_path))
    if inp is None:
        return {}
    attrs = {a.name: a.value for a in inp.spec().extra_attribs}
    inp.close()
    out = {}
    for key, name in (
        ("sync_seconds", "synchronization_time"),
        ("cycles_render_seconds", "render_time"),
    ):
        value = next((v for k, v in attrs.items() if k.endswith("." + name)), None)
        if isinstance(value, str):
            try:
                out[key] = _seconds(value)
            except ValueError:
                pass
    return out


def render_result(log_path=None) -> bpy.types.Image:
    """Render the current scene's camera; its Render Result image."""
    with quiet(log_path):
        bpy.ops.render.render(write_still=False)
    result = bpy.data.images.get("Render Result")
    if result is None:
        raise UserError("Blender produced no image (run with --verbose to see its output)")
    return result


def render(scene: bpy.types.Scene, out_dir: Path, description: dict, log_path=None) -> dict:
    """Render the scene's camera and write the three outputs into ``out_dir`` whole."""
    out_dir = check_writable(out_dir)
    start = time.perf_counter()
    result = render_result(log_path)
    elapsed = time.perf_counter() - start
    with atomic_paths(*(out_dir / name for name in OUTPUT_FILES)) as (exr, png, js):
        with quiet(log_path, stderr=True):
            _save(scene, result, exr, "exr")
            _save(scene, result, png, "png")
        description = dict(
            description,
            render_seconds=round(elapsed, 3),
            **cycles_times(exr),
            samples=(
                scene.cycles.samples
                if scene.render.engine == 'CYCLES'
                else scene.eevee.taa_render_samples
            ),
            engine=scene.render.engine,
            view_transform=scene.view_settings.view_transform,
            blender=bpy.app.version_string,
        )
        js.write_text(json_text(description))
    return description
