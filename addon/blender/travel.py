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

Nothing is deleted: a file already in the folder with the same size is kept, so a folder
written by an earlier save may hold files no longer read (a world since replaced).
"""

from __future__ import annotations

from pathlib import Path

import bpy

from . import model_node, osl_shader
from ..core.cache import MANIFEST, cache_dir
from ..core.errors import UserError
from ..core.files import copy_file
from ..core.paths import clean

FOLDER_SUFFIX = "_ctlab"
# The OSL shader's file inputs (osl/cook_torrance.osl): a file, or a folder of tables.
FILE_INPUTS = ("hdri", "tables", "ibl_bake", "env_marginal", "env_conditional", "env_pdf_table")

_restore: list = []  # (material, node name, input, value) to put back after the save


def files_folder(blend: Path) -> Path:
    """The folder beside ``blend`` that carries its OSL materials' files."""
    blend = Path(blend)
    return blend.with_name(blend.stem + FOLDER_SUFFIX)


def _ours(folder: Path) -> bool:
    """A folder of the add-on's: a cache entry, or one copied beside a .blend by an earlier
    save (read from there when the file was opened without syncing)."""
    parent = folder.parent
    return parent == cache_dir(create=False) or parent.name.endswith(FOLDER_SUFFIX)


def _carry(entry: Path, dest: Path) -> None:
    """Copy a cache entry's files into ``dest`` (each whole), but those already there."""
    dest.mkdir(parents=True, exist_ok=True)
    for f in sorted(entry.iterdir()):
        if f.name.startswith(".") or f.name == MANIFEST or not f.is_file():
            continue
        target = dest / f.name
        if not target.is_file() or target.stat().st_size != f.stat().st_size:
            copy_file(f, target)


def portable_path(value: str, blend: Path) -> str | None:
    """The value an OSL file input is saved with in ``blend``: a ``//`` path into the files
    folder for the add-on's files (copied there), a ``//`` path for a file inside the .blend's
    folder, or None to keep ``value`` (empty, missing, or a file of the user's elsewhere)."""
    if not value:
        return None
    path = Path(bpy.path.abspath(value))
    if not path.exists():
        return None
    entry = path if path.is_dir() else path.parent
    if _ours(entry):
        folder = files_folder(blend)
        if entry != folder / entry.name:
            _carry(entry, folder / entry.name)
        target = folder / entry.name / (path.name if path.is_file() else "")
        return bpy.path.relpath(str(target).rstrip("/"), start=str(blend.parent))
    if blend.parent in path.parents:
        return bpy.path.relpath(str(path), start=str(blend.parent))
    return None


def _osl_nodes():
    for mat, node in model_node.model_materials():
        if mat.library is None and model_node.implementation(node) == "osl":
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
def on_save_post(*_args) -> None:
    """After the file is written: the open session reads the cache again."""
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
