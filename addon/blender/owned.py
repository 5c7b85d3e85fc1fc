"""The add-on's own data-blocks, known by identity, not by name.

The project's rule (docs/bad-input.md): a file or data-block the program did not write is
never deleted, replaced or rebuilt; the same name is not the same owner. Every node group,
image, text, world and material the add-on makes carries a mark (``mark``: the extension's
id and version, blender_manifest.toml, and the block's role); ``is_ours`` asks for it and
``find`` returns the add-on's block of a role, never a user's block of the same name. Where
a user's block holds the name, the add-on's gets another (Blender's ".001").

Files written before the mark carry a role's older tag (``LEGACY``: the node group's
``ctlab_node_group`` and its sub-groups', the matrix's ``ctlab_matrix``, the materials'
``ctlab_generated``): those are recognised as ours too.

The images the node group packs into the file (node_group._float_image) are checked against
the file they were packed from once per loaded block (``packed_intact``): packed bytes changed
in the .blend are made again from the add-on's cache (``repack``).
"""

from __future__ import annotations

import hashlib
import re
import tomllib
from pathlib import Path

import bpy

from ..core.files import PACKAGE_ROOT

OWNER = "ctlab_owner"  # custom property: "<id> <version>" of the extension that made the block
ROLE = "ctlab_role"  # custom property: what the block is to the add-on

# roles; a node group's is its older tag (blender/node_group.py TAG, LIGHT_GROUP, ...)
NODE_GROUP = "ctlab_node_group"
LIGHT_GROUP = "ctlab_light_group"
CORRECTION_GROUP = "ctlab_correction_group"
PREFILTERED_GROUP = "ctlab_prefiltered_group"
MATRIX = "ctlab_matrix"  # the sphere matrix's world and collection (blender/scene_builder.py)
MATERIAL = "ctlab_material"  # materials.py's generated materials
OSL_TEXT = "ctlab_osl_text"  # a shader's source (blender/osl_shader.py)
OSL_GROUP = "ctlab_osl_group"  # the model's compiled shader, shared (blender/osl_shader.py)
TABLE_IMAGE = "ctlab_table_image"  # a baked file or table, packed (node_group._float_image)
DATA_IMAGE = "ctlab_data_image"  # a pixel grid's data (blender/pixel_grid.py)
PLOT_IMAGE = "ctlab_plot_image"  # the BRDF plot shown in the Image Editor (ui/operators/jobs.py)
# the tag a role's blocks carried before the mark (old files, cache entries, the shipped group)
LEGACY = {
    NODE_GROUP: NODE_GROUP,
    LIGHT_GROUP: LIGHT_GROUP,
    CORRECTION_GROUP: CORRECTION_GROUP,
    PREFILTERED_GROUP: CORRECTION_GROUP,  # the pre-filtered chain was tagged as the correction
    MATRIX: MATRIX,
    MATERIAL: "ctlab_generated",
}
_SUFFIX = re.compile(r"\.\d{3,}$")  # Blender's ".001" on a taken name


def _manifest() -> tuple:
    """The extension's id and version (blender_manifest.toml)."""
    try:
        with open(PACKAGE_ROOT / "blender_manifest.toml", "rb") as f:
            data = tomllib.load(f)
        return str(data["id"]), str(data["version"])
    except (OSError, KeyError, tomllib.TOMLDecodeError):
        return "cook_torrance_lab", "?"


ADDON_ID, VERSION = _manifest()


def mark(block: bpy.types.ID, role: str) -> bpy.types.ID:
    """Mark a block the add-on made (its id and version, and the role)."""
    block[OWNER] = f"{ADDON_ID} {VERSION}"
    block[ROLE] = role
    return block


def is_ours(block: bpy.types.ID | None, role: str) -> bool:
    """Whether the add-on made ``block`` for ``role``: its mark, or where it has none, the
    role's older tag (``LEGACY``). A block from a linked library is that file's."""
    if block is None or block.library is not None:
        return False
    owner = block.get(OWNER)
    if owner is not None:
        return str(owner).split(" ")[0] == ADDON_ID and block.get(ROLE) == role
    tag = LEGACY.get(role)
    return tag is not None and bool(block.get(tag))


def carries_mark(block: bpy.types.ID | None, role: str) -> bool:
    """Whether ``block`` carries the add-on's mark for ``role``, wherever it comes from (a
    linked library, a copy the user made): what it is, for reading. Whether the add-on may
    change or remove it is ``is_ours``."""
    if block is None:
        return False
    owner = block.get(OWNER)
    return owner is not None and str(owner).split(" ")[0] == ADDON_ID and block.get(ROLE) == role


def find(collection, name: str, role: str, where=None):
    """The add-on's block of ``role`` named ``name`` (or ``name`` with Blender's ".001"
    where a user's block held the name) in ``collection`` (bpy.data.node_groups, ...), the
    exact name first; None where the add-on has none, whoever holds the name. ``where``, a
    test a candidate must also pass."""
    best = None
    for block in collection:
        if block.name != name and _SUFFIX.sub("", block.name) != name:
            continue
        if is_ours(block, role) and (where is None or where(block)):
            if block.name == name:
                return block
            best = best if best is not None and best.name < block.name else block
    return best


def new(collection, name: str, role: str, *args, **kw):
    """A new block of the add-on in ``collection``, marked; Blender gives it another name
    where ``name`` is taken."""
    return mark(collection.new(name, *args, **kw), role)


# --- Packed images ---------------------------------------------------------------------------

_intact: set = set()  # (session_uid, packed size) of the blocks checked in this process
_file_digests: dict = {}  # (path, mtime, size) -> sha256 of the file


def _digest(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def _file_digest(path: Path) -> str:
    stat = path.stat()
    key = (str(path), stat.st_mtime_ns, stat.st_size)
    if key not in _file_digests:
        _file_digests[key] = _digest(path.read_bytes())
    return _file_digests[key]


def packed_intact(image: bpy.types.Image, path: Path) -> bool:
    """Whether the image's packed bytes are those of ``path``, the file it was packed from
    (the add-on's cache). Hashed once per loaded block and packing (``ID.session_uid`` is
    new for each block a file load makes), so a sync costs no hash after the first."""
    key = (image.session_uid, image.packed_file.size)
    if key in _intact:
        return True
    if _digest(image.packed_file.data) != _file_digest(Path(path)):
        return False
    _intact.add(key)
    return True


def repack(image: bpy.types.Image) -> None:
    """Pack the image again from its file (the packed bytes are dropped, never written)."""
    image.unpack(method='REMOVE')
    image.reload()
    image.pack()
    _intact.add((image.session_uid, image.packed_file.size))


def check_packed_images() -> list:
    """Every packed image of the add-on (``TABLE_IMAGE``) whose bytes are not its file's,
    where that file exists, packed again from it; the names of those remade. Run when a file
    is loaded (blender/light_sync.py) and by each use (node_group._float_image)."""
    remade = []
    for image in bpy.data.images:
        if image.packed_file is None or not is_ours(image, TABLE_IMAGE):
            continue
        path = Path(bpy.path.abspath(image.filepath))
        if path.is_file() and not packed_intact(image, path):
            repack(image)
            remade.append(image.name)
    return remade
