"""A saved .blend renders the same without the add-on or its cache: on a render farm node, a
colleague's machine, or this one after the cache is cleared (docs/usage.md "What to send to a
render farm").

- The node group reads its tables and the world's bake through images, which are packed into
  the .blend when they are set (node_group._float_image): nothing to send.
- The OSL shader reads its files by path (OSL ``texture()``), which a packed image cannot
  serve. Cycles resolves a script node's string inputs as Blender paths, ``//`` being the
  .blend's folder (Cycles' Blender sync, ``set_default_value``: ``blender_absolute_path``).
  So when the file is saved, the files the OSL nodes read from the add-on's cache (the DFG
  and energy tables, the world's split-sum bake, its importance tables, a baked or uniform
  world) are copied into a folder beside the .blend, ``<name>_ctlab``, and the inputs are
  saved as ``//`` paths into it; an HDRI of the user's inside the .blend's folder is saved
  as a ``//`` path too. After the save the inputs get their cache paths back, so the open
  session keeps reading the cache (``save_pre`` / ``save_post`` handlers).

The folder is written through its write gate (core/gate.py): a file of the user's there, or
one ctlab wrote and the user changed, is never replaced (the save goes on, one line says the
files stay in the cache), and no link is followed. Nothing is deleted: a folder written by
an earlier save may hold files no longer read (a world since replaced).
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import bpy

from . import model_node, osl_shader
from ..core.cache import MANIFEST, cache_dir
from ..core.errors import UserError
from ..core.files import sha256
from ..core.gate import Gate
from ..core.paths import clean

FOLDER_SUFFIX = "_ctlab"
# The OSL shader's file inputs (osl/cook_torrance.osl): a file, or a folder of tables.
FILE_INPUTS = ("hdri", "tables", "ibl_bake", "env_marginal", "env_conditional", "env_pdf_table")

_restore: list = []  # (material, node name, input, value) to put back after the save
_saved_as: list = [""]  # the file as last opened or saved, which its // paths are relative to


def files_folder(blend: Path) -> Path:
    """The folder beside ``blend`` that carries its OSL materials' files."""
    blend = Path(blend)
    return blend.with_name(blend.stem + FOLDER_SUFFIX)


def _ours(folder: Path) -> bool:
    """A folder of the add-on's: a cache entry, or one copied beside a .blend by an earlier
    save (read from there when the file was opened without syncing)."""
    parent = folder.parent
    return parent == cache_dir(create=False) or parent.name.endswith(FOLDER_SUFFIX)


def _carry(entry: Path, folder: Path) -> None:
    """Copy a cache entry's files into ``folder/<entry name>`` through the folder's write gate
    (core.gate): a file there of the same content is kept as it is; one ctlab wrote there
    (its record) is replaced; any other, the user's, or a link on the way, is refused in one
    line and nothing is copied."""
    sources = {
        f"{entry.name}/{f.name}": f
        for f in sorted(entry.iterdir())
        if not f.name.startswith(".") and f.name != MANIFEST and f.is_file()
    }
    gate = Gate(folder, "the OSL materials' files")
    needed = {}
    for rel, f in sources.items():
        target = folder / rel
        if target.is_file() and not target.is_symlink() and sha256(target) == sha256(f):
            continue  # the same bytes: nothing to write
        needed[rel] = f
    if needed:
        gate.write({rel: _copy(f) for rel, f in needed.items()}, inputs=list(needed.values()))


def _copy(source: Path):
    def write(tmp: Path) -> None:
        shutil.copyfile(source, tmp)

    return write


def _resolve(value: str) -> Path:
    """An input's file: a ``//`` path from the folder of the file as it was last opened or
    saved (``_saved_as``), whatever Blender's current file path says during a Save As."""
    start = os.path.dirname(_saved_as[0] or bpy.data.filepath) or None
    return Path(bpy.path.abspath(value, start=start))


def portable_path(value: str, blend: Path) -> str | None:
    """The value an OSL file input is saved with in ``blend``: a ``//`` path into the files
    folder for the add-on's files (copied there), a ``//`` path for a file inside the .blend's
    folder, the absolute path of a file elsewhere that was given relative to the old file's
    folder (a Save As into another folder), or None to keep ``value`` (empty, missing, or an
    absolute path of the user's elsewhere)."""
    if not value:
        return None
    path = _resolve(value)
    if not path.exists():
        return None
    entry = path if path.is_dir() else path.parent
    if _ours(entry):
        folder = files_folder(blend)
        if entry != folder / entry.name:
            _carry(entry, folder)
        target = folder / entry.name / (path.name if path.is_file() else "")
        return bpy.path.relpath(str(target).rstrip("/"), start=str(blend.parent))
    if blend.parent in path.parents:
        return bpy.path.relpath(str(path), start=str(blend.parent))
    return str(path) if value.startswith("//") else None


def _osl_nodes():
    """The file's OSL model nodes, one per script node (materials share a group's)."""
    seen = set()
    for mat, node in model_node.model_materials():
        if mat.library is None and model_node.implementation(node) == "osl":
            script = osl_shader.script_node(node)
            if (script.id_data.session_uid, script.name) not in seen:
                seen.add((script.id_data.session_uid, script.name))
                yield mat, node


@bpy.app.handlers.persistent
def on_save_pre(filepath="", *_args) -> None:
    """Before the file is written: its OSL materials' files beside it (portable_path)."""
    _restore.clear()
    if not filepath:
        return
    try:
        blend = clean(bpy.path.abspath(filepath), "saved file")
        for mat, node in _osl_nodes():
            for key in FILE_INPUTS:
                sock = osl_shader.socket(node, key)
                saved = portable_path(sock.default_value, blend)
                if saved is not None and saved != sock.default_value:
                    _restore.append((mat, node.name, key, sock.default_value))
                    sock.default_value = saved
    except (UserError, OSError) as exc:
        why = (
            f"{exc.strerror}: {exc.filename}"
            if isinstance(exc, OSError) and exc.strerror and exc.filename
            else str(exc)
        )
        print(
            f"Cook-Torrance Lab: the OSL materials' files could not be put beside "
            f"{filepath} ({why}); the file reads them from this machine's cache"
        )


@bpy.app.handlers.persistent
def on_load_post(*_args) -> None:
    """The file just opened: its // paths are relative to it."""
    _saved_as[0] = bpy.data.filepath


@bpy.app.handlers.persistent
def on_save_post(*_args) -> None:
    """After the file is written: the open session reads the cache again (and its // paths
    are relative to the file as now saved)."""
    _saved_as[0] = bpy.data.filepath
    for mat, name, key, value in _restore:
        node = mat.node_tree.nodes.get(name)
        if node is not None:
            osl_shader.socket(node, key).default_value = value
    _restore.clear()


def _handlers():
    """(handler list, handler): a failed save restores the inputs too (save_post_fail, in
    every supported Blender)."""
    h = bpy.app.handlers
    return (
        (h.save_pre, on_save_pre),
        (h.save_post, on_save_post),
        (h.save_post_fail, on_save_post),
        (h.load_post, on_load_post),
    )


def register_handlers() -> None:
    for handlers, handler in _handlers():
        if handler not in handlers:
            handlers.append(handler)


def unregister_handlers() -> None:
    for handlers, handler in _handlers():
        while handler in handlers:
            handlers.remove(handler)
    _restore.clear()
