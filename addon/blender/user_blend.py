"""A user's own .blend for a job (``ctlab scene``, ``ctlab export``): checked by its first
bytes, opened with its scripts off and never saved, its camera, the materials that render, the
files it reads (linked libraries and missing images refused, before anything is written), and
its OSL model nodes given this version of the shader."""

from __future__ import annotations

import os
from pathlib import Path

import bpy

from . import model_node, node_group, osl_shader, renderer
from ..core.errors import UserError

# The first bytes of a .blend: plain, gzip (before 3.0) or zstd (3.0 and later) compressed.
BLEND_MAGIC = (b"BLENDER", b"\x1f\x8b", b"\x28\xb5\x2f\xfd")


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
