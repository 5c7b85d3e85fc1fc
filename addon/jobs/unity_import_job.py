"""``ctlab import-unity PATH --out FILE.blend`` and the operator *Unity Materials (.mat /
folder)*: a Unity project's built-in Standard (metallic) materials as Cook-Torrance
materials (core/unity/read.py reads the files, core/unity/standard.py says what each
material means; blender/unity_import.py builds the materials).

PATH is a ``.mat`` or a folder: a Unity project (its Assets and Packages), an Assets folder
or any folder below one; the textures are found through the ``.meta`` guids under it (a lone
``.mat``: under its nearest Assets folder). Every material whose shader is exactly Standard
(fileID 46 of the built-in guid) is imported; any other shader is listed and skipped, one
line each. Nothing under PATH is written. A ``.mat`` named as PATH that cannot be read is
bad input (one line, exit status 2); inside a folder it is listed and skipped. A texture
that resolves nowhere is a warning, and the material is kept without it.

The .blend is new (Blender's empty factory file plus the materials, each with a fake user)
and written whole: saved as a copy to a staged sibling, then renamed (core.files). An
existing --out is never replaced without ``force``, and never when it is not a .blend."""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

from ..core import files
from ..core.errors import UserError
from ..core.unity import read as unity
from ..core.unity import standard

BLEND_MAGIC = (b"BLENDER", b"\x28\xb5\x2f\xfd", b"\x1f\x8b")  # plain, zstd, gzip


@dataclass
class UnityImport:
    """What a Unity path holds for the import, read before anything is built."""

    surfaces: list = field(default_factory=list)  # core.unity.standard.Surface
    skipped: list = field(default_factory=list)  # one line each: other shaders, unreadable
    warnings: list = field(default_factory=list)
    roots: list = field(default_factory=list)  # the folders read


def _display(path: Path, roots: list) -> str:
    for root in roots:
        try:
            return str(Path(path).relative_to(root.parent))
        except ValueError:
            continue
    return str(path)


def read_unity(path: Path) -> UnityImport:
    """Every Standard material of ``path`` (a ``.mat`` or a folder) as a Surface; the
    others listed. A ``.mat`` given as ``path`` that cannot be read is a UserError."""
    path = Path(path)
    if path.is_dir():
        roots = standard.project_roots(path)
        project = standard.scan(roots)
        mats = project.materials
        if not mats:
            raise UserError(
                f"{path} holds no Unity material (.mat); give a Unity project, its "
                "Assets folder or a .mat file"
            )
    elif path.is_file():
        if path.suffix.lower() != ".mat":
            raise UserError(f"{path} is not a Unity material (.mat) or folder")
        text = unity.read_text(path, "Unity material")
        unity.read_material(text, str(path))  # bad input: refused before the folder is read
        roots = [standard.assets_root_of(path)]
        project = standard.scan(roots)
        mats = [path]
    else:
        raise UserError(f"no such file or folder: {path}; give a .mat file or a Unity project")
    out = UnityImport(roots=roots)
    out.warnings += [f"skipped a .meta file: {p}" for p in project.problems]
    for mat_path in mats:
        shown = _display(mat_path, roots) if path.is_dir() else str(mat_path)
        try:
            mat = unity.read_material(unity.read_text(mat_path, "Unity material"), shown)
        except UserError as exc:
            if path.is_file():
                raise
            out.skipped.append(str(exc))
            continue
        if not mat.is_standard:
            out.skipped.append(f"{shown} ({mat.name}): {standard.shader_label(mat, project)}")
            continue
        out.surfaces.append(standard.surface(mat, project.assets))
    return out


def check_out(out: Path, force: bool, inputs=()) -> Path:
    """The .blend to write: a .blend path in an existing folder, outside the Unity folders
    read; an existing file only with ``force`` and only when it is a .blend."""
    out = Path(out)
    if out.suffix.lower() != ".blend":
        raise UserError(f"--out {out} is not a .blend file name; give FILE.blend")
    if not out.parent.is_dir():
        raise UserError(f"--out's folder {out.parent} does not exist")
    for root in inputs:
        root = Path(root).resolve()
        if out.resolve() == root or root in out.resolve().parents:
            raise UserError(
                f"--out {out} lies inside the Unity folder {root}, which is read and never "
                "written; write the .blend elsewhere"
            )
    if os.path.lexists(out):
        if os.path.islink(out) or not os.path.isfile(out):
            raise UserError(f"--out {out} exists and is not a regular file; nothing was written")
        try:
            with open(out, "rb") as f:
                head = f.read(8)
        except OSError as exc:
            raise UserError(f"--out {out} cannot be read ({exc.strerror or exc})") from None
        if not head.startswith(BLEND_MAGIC):
            raise UserError(
                f"--out {out} exists and is not a .blend file; it is left alone (nothing was "
                "written)"
            )
        if not force:
            raise UserError(f"--out {out} exists; give --force to replace it (nothing was written)")
    return out


def build(found: UnityImport, impl: str = "nodes", scene=None) -> tuple:
    """The materials in the open file; (materials, warnings)."""
    from ..blender.unity_import import build_material

    materials, warnings = [], list(found.warnings)
    for s in found.surfaces:
        mat, w = build_material(s, impl, scene)
        materials.append(mat)
        warnings += w
    return materials, warnings


def run_import(path: Path, out: Path, log=None, force: bool = False, impl: str = "nodes") -> dict:
    """Read ``path``, build its Standard materials in a new file, save it as ``out``."""
    import bpy

    from ..blender import renderer

    found = read_unity(path)
    check_out(out, force, found.roots + ([Path(path)] if Path(path).is_dir() else []))
    if not found.surfaces:
        raise UserError(
            f"{path} holds no material of Unity's built-in Standard shader "
            f"({len(found.skipped)} other material(s): "
            + "; ".join(found.skipped[:3])
            + ("; ..." if len(found.skipped) > 3 else "")
            + "); nothing was written"
        )
    with renderer.quiet(log):
        bpy.ops.wm.read_factory_settings(use_empty=True)
    materials, warnings = build(found, impl, bpy.context.scene)  # lit as New Material does
    with files.atomic_path(out) as tmp:
        with renderer.quiet(log):
            bpy.ops.wm.save_as_mainfile(filepath=str(tmp), copy=True)
    return {
        "materials": [
            {"name": m.name, "source": s.source, "not_carried": list(s.not_carried)}
            for m, s in zip(materials, found.surfaces)
        ],
        "skipped": found.skipped,
        "warnings": warnings,
        "written": str(out),
    }
