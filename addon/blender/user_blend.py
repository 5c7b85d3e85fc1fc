"""A user's own .blend for a job (``ctlab scene``, ``ctlab export``): checked by its first
bytes, opened with its scripts off and never saved, its camera, the materials that render, the
files it reads (linked libraries and missing images refused, before anything is written), and
its OSL model nodes given this version of the shader."""

from __future__ import annotations

import os
import re
from pathlib import Path

import bpy

from . import model_node, node_group, osl_shader, renderer
from ..core.errors import UserError

# The first bytes of a .blend: plain, gzip (before 3.0) or zstd (3.0 and later) compressed.
BLEND_MAGIC = (b"BLENDER", b"\x1f\x8b", b"\x28\xb5\x2f\xfd")
# A plain .blend's header: "BLENDER", the pointer size ('_' 4 bytes, '-' 8), the byte order
# ('v' little, 'V' big) and the version (3 digits), 12 bytes; or since Blender 5.0
# "BLENDER17-01v0502": the header's size (17), the file format (01), 'v', the version (4
# digits), whose blocks have 8-byte pointers and 64-bit lengths. The header's size and its
# blocks' header size (BHead: code, length, old pointer, SDNA index, count).
_HEADERS = (
    (re.compile(rb"BLENDER_[vV][0-9]{3}"), 12, 20),
    (re.compile(rb"BLENDER-[vV][0-9]{3}"), 12, 24),
    (re.compile(rb"BLENDER17-01[vV][0-9]{4}"), 17, 32),
)
# The smallest .blend Blender writes (an empty file) is hundreds of kilobytes; a compressed
# one is at least a stream header and a block.
MIN_COMPRESSED = 32


def _blend_problem(head: bytes, tail: bytes, size: int) -> str | None:
    """Why the bytes are not a whole .blend, or None: a plain file's header must be one of
    _HEADERS and its last block the end block (ENDB), so that a file cut short, or a header
    alone, is refused before Blender reads it (Blender reads a header-only file into a
    failed allocation: "Malloc returns null")."""
    if head.startswith(b"BLENDER"):
        for pattern, header, bhead in _HEADERS:
            if pattern.fullmatch(head[:header]):
                if size < header + 2 * bhead:
                    return "holds a header and no data"
                if tail[-bhead:][:4] != b"ENDB":
                    return "is cut short (no end block)"
                return None
        return "has a header Blender does not write"
    if size < MIN_COMPRESSED:
        return "is cut short (a compressed header and no data)"
    return None


def check_blend_file(path: Path) -> Path:
    """An existing, readable Blender file (by its first bytes, not its name), whole: a plain
    file's header and end block are checked before Blender reads it (``_blend_problem``)."""
    path = Path(path)
    if not path.exists():
        raise UserError(f"no such file: {path}; give a .blend file")
    if not path.is_file():
        raise UserError(f"{path} is not a file; give a .blend file")
    try:
        with open(path, "rb") as f:
            head = f.read(17)
            size = os.fstat(f.fileno()).st_size
            f.seek(max(0, size - 64))
            tail = f.read(64)
    except OSError as exc:
        raise UserError(f"cannot read {path} ({exc.strerror or exc})") from None
    if not any(head.startswith(m) for m in BLEND_MAGIC):
        raise UserError(f"{path} is not a Blender file (.blend); give one saved by Blender")
    problem = _blend_problem(head, tail, size)
    if problem is not None:
        raise UserError(
            f"{path} is not a whole Blender file: it {problem} ({size} bytes); give one "
            "saved by Blender"
        )
    return path.resolve()


def check_libraries(path: Path) -> None:
    """Linked libraries whose file is missing are refused (one line, as ``check_data`` refuses
    any library for ``ctlab scene``): Blender opens the file with placeholders for their data,
    whose materials hold no node tree, so an export would leave them out silently."""
    for lib in bpy.data.libraries:
        if lib.packed_file is not None or getattr(lib, "is_archive", False):
            continue  # packed into the file (5.x): nothing to find on disk
        where = bpy.path.abspath(lib.filepath, library=lib.parent)
        if getattr(lib, "is_missing", False) or not where or not os.path.isfile(where):
            shown = where.encode("utf-8", "surrogateescape").decode("utf-8", "replace")
            raise UserError(
                f"{path.name} links data from {lib.name}, whose file is missing "
                f"({shown or 'no path'}); find it (File > External Data > Find Missing Files, "
                "or relocate the library in the Outliner's Blender File view) or make its "
                "data local, and save"
            )
    for mat in bpy.data.materials:
        if mat.library is not None and mat.is_missing:
            raise UserError(
                f"{path.name} links material {mat.name!r} from {mat.library.name}, which no "
                "longer holds it; relink it (or make a local material of that name), and save"
            )


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
    the text datablock refreshed and each script node recompiled (a shared group's once),
    keeping its values."""
    current = osl_shader.source()
    stale = {}
    for n in nodes:
        if model_node.implementation(n) == "osl":
            script = osl_shader.script_node(n)
            if script.script.as_string() != current:
                stale[script.id_data.session_uid, script.name] = (n, script)
    for node, script in stale.values():
        if script is node:
            osl_shader.compile_script_node(node)
        else:
            osl_shader.refresh_group(node.node_tree)
