"""Baking a world node tree (a Sky Texture, gradients, mixes: anything Cycles renders as the
world) to an equirectangular float EXR the model can light with.

Cycles on the CPU renders a temporary scene that holds a copy of the world and nothing else
through a panoramic equirectangular camera, one sample per pixel at the pixel's centre (a box
filter of width 0.01), no denoising, Standard view transform, saved as a 32-bit float RGB EXR
of the raw values. The camera turned (90 deg, 0, -90 deg) makes the image's mapping Blender's
Environment Texture mapping: direction d is at s = 0.5 - atan2(d.y, d.x) / 2 pi,
t = 0.5 + atan2(d.z, hypot(d.x, d.y)) / pi, the file's top row +Z (tests/render/test_world_bake.py
checks it against forest.exr and an analytic gradient).

A Sky Texture's sun disc (about half a degree, a few pixels) would be missed or over-counted
by one sample at each pixel centre (its light off by a factor 4 either way): the pixels around
each disc are rendered again, SUN_SAMPLES samples each spread over the whole pixel (a box
filter one pixel wide), and pasted in.

The Background node that feeds the World Output directly with an unlinked Strength is baked
at strength 1: its strength stays outside the bake, where the HDRI Strength driver reads it
(blender/drivers.py world_lighting), so dragging it never bakes again. Every other value
(a Mapping rotation included) is inside the bake.

The result is cached (core/cache.py) under a key computed from the tree's content
(blender/world_signature.py: node types, their properties, input values and links, node groups
followed, image files' content hashes), the width and the Blender version. The user's scene
and world are never changed; Cycles' Render Result keeps a render slot of its own for the
bakes (named SLOT, added once: Python cannot remove a slot), so the user's last render stays
in its slot.
"""

from __future__ import annotations

import math
from pathlib import Path

import bpy

from . import compat
from ..core import cache
from ..core.errors import UserError
from ..core.hdri import read_pixels, write_float_exr
from .drivers import world_lighting
from .world_signature import signature

FILE = "world.exr"
SLOT = "Cook-Torrance Lab world bake"
_busy = False  # a bake is rendering (the depsgraph handler then stands aside)


def busy() -> bool:
    """Whether a bake is rendering now (its temporary scene causes depsgraph updates)."""
    return _busy


# ----------------------------------------------------------------------------------------
# The bake


def summary(world: bpy.types.World) -> str:
    """The kinds of node that make the world, for the panel: 'Sky Texture', 'Gradient
    Texture, Mix'."""
    skip = {
        "ShaderNodeOutputWorld",
        "ShaderNodeBackground",
        "NodeReroute",
        "NodeFrame",
        "ShaderNodeTexCoord",
    }
    labels = sorted({n.bl_label for n in world.node_tree.nodes if n.bl_idname not in skip})
    if not labels:
        return "Background"
    return ", ".join(labels[:3]) + (", ..." if len(labels) > 3 else "")


def _configure(scene: bpy.types.Scene, width: int) -> None:
    from . import renderer

    renderer.set_converging_cycles(scene, False, 1, 0)  # one sample at each pixel centre
    r = scene.render
    r.resolution_x, r.resolution_y, r.resolution_percentage = width, width // 2, 100
    r.film_transparent = False
    r.use_compositing = False
    r.use_sequencer = False
    cy = scene.cycles
    cy.pixel_filter_type = 'BOX'  # the world at each pixel centre
    cy.filter_width = 0.01
    cy.max_bounces = 0
    vs = scene.view_settings
    vs.view_transform = 'Standard'
    vs.look = 'None'
    vs.exposure = 0.0
    vs.gamma = 1.0


def _camera(scene: bpy.types.Scene) -> bpy.types.Object:
    cam = bpy.data.cameras.new("Cook-Torrance Lab world bake")
    cam.type = 'PANO'
    if hasattr(cam, "panorama_type"):  # 4.0 and later
        cam.panorama_type = 'EQUIRECTANGULAR'
    else:
        cam.cycles.panorama_type = 'EQUIRECTANGULAR'
    holder = cam if hasattr(cam, "longitude_min") else cam.cycles
    holder.longitude_min, holder.longitude_max = -math.pi, math.pi
    holder.latitude_min, holder.latitude_max = -math.pi / 2, math.pi / 2
    obj = bpy.data.objects.new(cam.name, cam)
    # Camera -Z looks along world +X, its +Y is world +Z: image centre = +X, u grows
    # toward -Y (Environment Texture: s = 0.5 - atan2(y, x) / 2 pi)
    obj.rotation_euler = (math.pi / 2, 0.0, -math.pi / 2)
    scene.collection.objects.link(obj)
    scene.camera = obj
    return obj


SUN_SAMPLES = 1024  # per pixel of a sun disc's region (a box filter one pixel wide)
SUN_MARGIN = 2  # pixels around the disc


def _sun_discs(world):
    """The world's Sky Textures that draw a sun disc where their direction is the world's
    (their Vector unlinked): a disc about half a degree wide, which one sample at each pixel
    centre would miss (its light lost) or hit (its light counted over whole pixels)."""
    return [
        n
        for n in world.node_tree.nodes
        if n.bl_idname == "ShaderNodeTexSky"
        and not n.mute
        and getattr(n, "sun_disc", False)
        and n.sky_type not in ('PREETHAM', 'HOSEK_WILKIE')
        and not any(sock.is_linked for sock in n.inputs)
    ]


def _sun_regions(sky, width):
    """The pixel rectangles ((row0, row1), (col0, col1)), rows from the top, that hold the
    Sky Texture's sun disc with a margin (two when it straddles the image's seam). Its sun
    is at elevation e and azimuth atan2(y, x) = 90 deg - rotation (measured in 4.5 and 5.2)."""
    h = width // 2
    e = sky.sun_elevation
    phi = math.pi / 2 - sky.sun_rotation
    a = sky.sun_size / 2 + 1e-3
    centre_row = (0.5 - e / math.pi) * h
    rows = (
        max(0, math.floor(centre_row - a / math.pi * h) - SUN_MARGIN),
        min(h, math.ceil(centre_row + a / math.pi * h) + SUN_MARGIN),
    )
    e_max = max(abs(e - a), abs(e + a))
    if e_max >= math.radians(85):
        return [(rows, (0, width))]
    half = math.asin(min(1.0, math.sin(a) / math.cos(e_max))) / (2 * math.pi) * width
    centre_col = ((0.5 - phi / (2 * math.pi)) % 1.0) * width
    c0 = math.floor(centre_col - half) - SUN_MARGIN
    c1 = math.ceil(centre_col + half) + SUN_MARGIN
    if c1 - c0 >= width:
        return [(rows, (0, width))]
    if c0 < 0:
        return [(rows, (0, c1)), (rows, (c0 + width, width))]
    if c1 > width:
        return [(rows, (c0, width)), (rows, (0, c1 - width))]
    return [(rows, (c0, c1))]


def _refine(scene, width, rows, cols) -> None:
    """Render only ``rows`` x ``cols`` with many samples each spread over the whole pixel
    (the pixel's average)."""
    h = width // 2
    r = scene.render
    r.use_border = True
    r.use_crop_to_border = True
    r.border_min_x, r.border_max_x = cols[0] / width, cols[1] / width
    r.border_min_y, r.border_max_y = (h - rows[1]) / h, (h - rows[0]) / h  # from the bottom
    scene.cycles.samples = SUN_SAMPLES
    scene.cycles.filter_width = 1.0


def _render_pass(scene, path: Path) -> None:
    from . import renderer

    try:
        bpy.ops.render.render(write_still=False, scene=scene.name)
    except RuntimeError as exc:
        raise UserError(
            f"the world could not be baked: {str(exc).strip().splitlines()[-1]}"
            " (is a render running? sync the lighting again after it)"
        ) from None
    image = bpy.data.images.get("Render Result")
    if image is None:
        raise UserError("the world could not be baked: Cycles gave no render result")
    renderer.save_exr(scene, image, path)
    if not path.is_file():
        raise UserError(f"the world could not be baked: {path} was not written")


def render(world: bpy.types.World, width: int, path: Path) -> None:
    """Render ``world`` (a copy of it, its output Background at strength 1) to ``path``."""
    global _busy
    frame = bpy.context.scene.frame_current if bpy.context.scene is not None else 1
    lighting = world_lighting(world)
    copy = scene = obj = None
    result = bpy.data.images.get("Render Result")
    slot = slot_index = None
    _busy = True
    try:
        copy = world.copy()
        copy.name = "Cook-Torrance Lab world bake"
        if lighting.background is not None:
            copy.node_tree.nodes[lighting.background.name].inputs["Strength"].default_value = 1.0
        settings = getattr(copy, "cycles", None)
        if settings is not None:
            settings.sampling_method = 'NONE'  # nothing to light: no importance map
        scene = bpy.data.scenes.new("Cook-Torrance Lab world bake")
        scene.world = copy
        scene.frame_current = frame
        _configure(scene, width)
        obj = _camera(scene)
        if result is not None and result.type == 'RENDER_RESULT':
            # the user's last render stays in its slot
            slot_index = result.render_slots.active_index
            slot = next(
                (s for s in result.render_slots if s.name == SLOT), None
            ) or result.render_slots.new(name=SLOT)
            result.render_slots.active = slot
        regions = [r for sky in _sun_discs(world) for r in _sun_regions(sky, width)]
        if not regions:
            _render_pass(scene, path)
        else:
            full = path.with_name(".full.exr")
            _render_pass(scene, full)
            pixels = read_pixels(full, "world bake").copy()
            full.unlink()
            part = path.with_name(".sun.exr")
            for rows, cols in regions:
                _refine(scene, width, rows, cols)
                _render_pass(scene, part)
                crop = read_pixels(part, "world bake")
                part.unlink()
                if crop.shape[:2] != (rows[1] - rows[0], cols[1] - cols[0]):
                    raise UserError(
                        f"the world could not be baked: Cycles cropped the sun's "
                        f"region to {crop.shape[1]}x{crop.shape[0]} pixels"
                    )
                pixels[rows[0] : rows[1], cols[0] : cols[1]] = crop
            write_float_exr(path, pixels)
    finally:
        if slot is not None:
            result.render_slots.active_index = slot_index
        if obj is not None:
            cam = obj.data
            bpy.data.objects.remove(obj)
            bpy.data.cameras.remove(cam)
        if scene is not None:
            bpy.data.scenes.remove(scene)
        if copy is not None:
            bpy.data.worlds.remove(copy)
        _busy = False


def bake_world(world: bpy.types.World, width: int = 1024) -> Path:
    """The world's node tree rendered to an equirectangular float RGB EXR, ``width`` x
    ``width / 2`` (Blender's Environment Texture mapping; cached under the tree's content)."""
    if world is None or world.node_tree is None:
        raise UserError("the world has no node tree to bake; give the scene a world with nodes")
    width = int(width)
    if width < 4 or width % 2:
        raise ValueError(f"bake width must be an even number >= 4, not {width}")
    compat.expose_bundled_modules()
    key = f"world-{signature(world, width)}"
    folder = cache.cached(key, lambda stage: render(world, width, stage / FILE))
    return folder / FILE
