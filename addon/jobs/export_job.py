"""``ctlab export FILE.blend --format materialx|usd|gltf --out DIR`` and the operator *Export
Cook-Torrance as MaterialX*: the file's Cook-Torrance materials leave Blender
(core/export/network.py says how the model maps onto MaterialX; core/export/materialx.py,
core/export/usd.py and core/export/gltf.py write the formats; blender/material_export.py
reads the materials).

- materialx: ``DIR/<material>.mtlx`` per material (nodedef, nodegraph, the material)
- usd: ``DIR/<file>.usda``: a UsdShade Material per material with the MaterialX network,
  bound to a prim per object (named like the object; no geometry)
- gltf: ``DIR/<file>.gltf``: metallic-roughness materials (no meshes)

and the images they reference in ``DIR/textures/`` (only those: glTF's packed
metallic-roughness image is made from the metallic and smoothness maps, which it does not
reference). Everything is read and checked before anything
is written (bad input: one line, exit status 2); each file is written whole (core.files); the
.blend is opened, never saved.
"""

from __future__ import annotations

from pathlib import Path

from ..blender import material_export
from ..core.export import gltf, materialx, network, usd
from ..core.errors import UserError
from ..core.files import (
    atomic_path,
    check_writable,
    copy_file,
    refuse_overwrite,
    temporary_folder,
    write_json,
    write_text,
)
from ..core.paths import safe_name

FORMATS = ("materialx", "usd", "gltf")


def plan_outputs(materials: list, fmt: str, out: Path, stem: str) -> dict:
    """Output path -> text (or dict for JSON) of the format's documents."""
    if fmt == "materialx":
        docs, used = {}, set()
        for mat in materials:
            name = network.valid_name(safe_name(mat.name, "material"), used)
            docs[out / f"{name}.mtlx"] = materialx.mtlx_document(mat)
        return docs
    if fmt == "usd":
        return {out / f"{stem}.usda": usd.usda_document(materials)}
    if fmt == "gltf":
        return {out / f"{stem}.gltf": gltf.gltf_document(materials)}
    raise UserError(f"unknown --format {fmt!r}; choose one of: {', '.join(FORMATS)}")


def write_export(materials: list, files: list, fmt: str, out: Path, stem: str, inputs=()) -> list:
    """Write the format's documents and the textures into ``out`` (each file whole); the
    paths written."""
    if not materials:
        raise UserError("no Cook-Torrance material to export")
    docs = plan_outputs(materials, fmt, out, stem)
    if fmt == "gltf":  # the .gltf's images only: the packed image replaces the raw maps
        uris = {img["uri"] for doc in docs.values() for img in doc.get("images", ())}
        copied = [f for f in files if f.name in uris]
        packed = [n for n in map(gltf.metallic_roughness_name, materials) if n is not None]
    else:
        copied, packed = files, []
    textures = {out / f.name: f for f in copied}
    sources = [Path(f.source) for f in files if f.source]
    refuse_overwrite(
        list(inputs) + sources, list(docs) + list(textures) + [out / n for n in packed]
    )
    check_writable(out)
    written = []
    for path, f in textures.items():
        check_writable(path.parent)
        if f.source:
            copy_file(Path(f.source), path)
        else:
            with atomic_path(path) as tmp:
                Path(tmp).write_bytes(f.data)
        written.append(path)
    if fmt == "gltf":
        written += write_metallic_roughness(materials, files, out)
    for path, doc in docs.items():
        if isinstance(doc, dict):
            write_json(path, doc)
        else:
            write_text(path, doc)
        written.append(path)
    return written


def write_metallic_roughness(materials: list, files: list, out: Path) -> list:
    """glTF's packed metallic-roughness images (core.export.gltf.metallic_roughness_pixels),
    read from the maps' own files (a map packed in the .blend through a private temporary
    file): the maps themselves are not written into ``out``, which does not reference them."""
    from ..core.compare import read_image, write_png

    by_name = {f.name: f for f in files}
    written = []
    with temporary_folder("ctlab-export-") as tmp:

        def read(name: str):
            f = by_name[name]
            path = Path(f.source) if f.source else tmp / Path(name).name
            if not f.source and not path.exists():
                path.write_bytes(f.data)
            return read_image(path)[..., 0]

        for mat in materials:
            name = gltf.metallic_roughness_name(mat)
            if name is None:
                continue
            maps = {
                key: read(mat.textures[key].file)
                for key in ("metallic", "smoothness")
                if key in mat.textures
            }
            invert = "smoothness" in mat.textures and mat.textures["smoothness"].invert
            pixels = gltf.metallic_roughness_pixels(
                maps.get("metallic"), maps.get("smoothness"), invert
            )
            check_writable((out / name).parent)  # textures/ may hold no other image
            write_png(out / name, pixels)
            written.append(out / name)
    return written


def run_export(blend: Path, fmt: str, out: Path, log=None) -> dict:
    """Open ``blend`` (never saved), read its Cook-Torrance materials, write the export."""
    from ..blender.user_blend import check_blend_file, open_blend

    if fmt not in FORMATS:
        raise UserError(f"unknown --format {fmt!r}; choose one of: {', '.join(FORMATS)}")
    blend = check_blend_file(blend)
    open_blend(blend, log)
    materials, files, notes = material_export.read_materials()
    if not materials:
        raise UserError(
            f"{blend.name} has no Cook-Torrance material; convert one first (Material "
            "Properties > Cook-Torrance > Principled to Cook-Torrance)"
        )
    stem = safe_name(blend.stem, "export")
    written = write_export(materials, files, fmt, out, stem, inputs=[blend])
    return {
        "materials": [
            {
                "name": m.name,
                "exact": network.exact(m),
                "not_carried": (
                    gltf.gltf_not_carried(m) if fmt == "gltf" else network.not_carried(m)
                ),
            }
            for m in materials
        ],
        "written": [str(p) for p in written],
        "notes": notes,
    }
