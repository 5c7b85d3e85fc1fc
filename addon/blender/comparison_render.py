"""Cycles set for comparing two renders of a user's scene material by material
(``ctlab scene``): the same settings for both, the Material Index pass, and the Render
Result saved as Blender's multilayer EXR (``layers.exr``) beside renderer.render's files."""

from __future__ import annotations

from pathlib import Path

import bpy

from . import renderer
from ..core.compare import read_material_index
from ..core.files import atomic_path

RENDER_FILES = renderer.OUTPUT_FILES + ("layers.exr",)


def image_size(scene: bpy.types.Scene, size: int) -> tuple:
    """(width, height) with ``size`` the longer side and the camera's displayed aspect."""
    r = scene.render
    aspect = (r.resolution_x * r.pixel_aspect_x) / max(r.resolution_y * r.pixel_aspect_y, 1e-9)
    if aspect >= 1:
        return size, max(1, round(size / aspect))
    return max(1, round(size * aspect)), size


def set_comparison_render(
    scene: bpy.types.Scene, camera, size: int, samples: int, seed: int, osl: bool, notes: list
) -> tuple:
    """Cycles on the CPU, the same for both renders: the job's samples and seed, no denoiser,
    no adaptive sampling, exact path tracing (renderer.set_exact_path_tracing), OSL when a
    model node needs it; the file's light paths, filter and colour management are kept.
    Only the active view layer renders, with the Material Index pass; no compositor. What it
    changes that the user might not expect goes into ``notes``; returns (width, height)."""
    width, height = image_size(scene, size)
    renderer.set_converging_cycles(scene, osl, samples, seed)
    r = scene.render
    r.resolution_x, r.resolution_y = width, height
    r.resolution_percentage = 100
    r.pixel_aspect_x = r.pixel_aspect_y = 1.0
    r.use_border = False
    r.use_compositing = False
    r.use_sequencer = False
    r.use_single_layer = True
    scene.camera = camera
    layer = bpy.context.view_layer
    layer.use_pass_material_index = True
    if layer.material_override is not None:
        notes.append(f"view layer material override {layer.material_override.name!r} cleared")
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


def render_into(scene, folder: Path, description: dict, log) -> tuple:
    """Render, write render.exr, render.png, scene.json and layers.exr; (description, index)."""
    description = renderer.render(scene, folder, description, log)
    result = bpy.data.images.get("Render Result")
    with renderer.quiet(log):
        save_layers(scene, result, folder / "layers.exr")
    return description, read_material_index(folder / "layers.exr")
