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
from ..core import files
from ..core.export import gltf, materialx, network, usd
from ..core.export.names import export_names
from ..core.export.maps import metallic_roughness_pixels, texture_values, write_png_rgba_to
from ..core.errors import UserError
from ..core.gate import Gate, check_name, read_input
from ..core.paths import safe_name

FORMATS = ("materialx", "usd", "gltf", "unity")
WHAT = "the export's files"


def plan_outputs(materials: list, fmt: str, out: Path, stem: str) -> dict:
    """Output path -> text (or dict for JSON) of the format's documents (Unity's: written by
    ``unity_writers``, from the decoded maps)."""
    if fmt == "materialx":
        names = export_names(materials)
        return {out / n.mtlx: materialx.mtlx_document(m) for m, n in zip(materials, names)}
    if fmt == "usd":
        return {out / f"{stem}.usda": usd.usda_document(materials)}
    if fmt == "gltf":
        return {out / f"{stem}.gltf": gltf.gltf_document(materials)}
    if fmt == "unity":
        return {}
    raise UserError(f"unknown --format {fmt!r}; choose one of: {', '.join(FORMATS)}")


def unity_writers(materials: list, files_: list, pixels: dict, out: Path, stem: str) -> dict:
    """Unity's files (core/unity/mat.py ``unity_outputs``): relative path -> writer."""
    from ..core.unity import mat as unity_mat

    writers = {}
    outputs = unity_mat.unity_outputs(materials, [f.name for f in files_], pixels, stem)
    for rel, content in outputs.items():
        if isinstance(content, tuple) and content[0] == unity_mat.PNG_RGBA:
            rgba = content[1]
            writers[rel] = lambda tmp, a=rgba, r=rel: write_png_rgba_to(tmp, a, out / r)
        else:
            writers[rel] = _write_bytes(content)
    return writers


def _texture_label(f) -> str:
    return str(f.source) if f.source else f"the packed image of {f.name}"


def _decode(f, scratch: Path):
    """The texture's pixels (float, h x w x 3, or 4 with its alpha; the file's values, colour
    not multiplied by alpha), read before anything is written: a file that is not a readable
    image is one line naming it (the input, never the output)."""
    from ..core.hdri import read_pixels

    def read_image(path):
        return read_pixels(path, "image", keep=4)

    path = Path(f.source) if f.source else scratch / f"packed{Path(f.name).suffix}"
    if not f.source:
        try:
            path.write_bytes(f.data)
        except OSError as exc:
            raise UserError(
                f"cannot write a temporary copy of {_texture_label(f)} in {scratch.parent}: "
                f"{files.WRITE_ERRORS.get(exc.errno) or exc.strerror or exc}; free space "
                "there or set TMPDIR to another folder (nothing was written)"
            ) from None
    try:
        return read_input(path, "texture", read_image)
    except UserError as exc:
        why = " ".join(str(exc).split())[:160]
        raise UserError(
            f"texture {_texture_label(f)} is not a readable image ({why}); nothing was written"
        ) from None
    finally:
        if not f.source:
            path.unlink(missing_ok=True)


def _write_bytes(data: bytes):
    return lambda tmp: tmp.write_bytes(data)


def _copy(source: Path):
    def write(tmp: Path) -> None:
        tmp.write_bytes(read_input(source, "texture", Path.read_bytes))

    return write


def _png(pixels, final: Path):
    from ..core.compare import write_png_to

    return lambda tmp: write_png_to(tmp, pixels, final)


def write_export(
    materials: list,
    files_: list,
    fmt: str,
    out: Path,
    stem: str,
    inputs=(),
    force: bool = False,
) -> list:
    """Write the format's documents and the textures into ``out`` through its write gate
    (core.gate: a file ctlab did not write is never replaced, unless ``force``; no link is
    followed; every texture is read and decoded first; all files land together or none);
    the paths written."""
    if not materials:
        raise UserError("no Cook-Torrance material to export")
    out = Path(out)
    docs = plan_outputs(materials, fmt, out, stem)
    if fmt == "gltf":  # the .gltf's images only: the packed image replaces the raw maps
        uris = {img["uri"] for doc in docs.values() for img in doc.get("images", ())}
        copied = [f for f in files_ if f.name in uris]
    elif fmt == "unity":  # albedo and normal: Unity's packed map replaces the others
        from ..core.unity import mat as unity_mat

        used = unity_mat.referenced_textures(materials)
        copied = [f for f in files_ if f.name in used]
    else:
        copied = files_
    for f in files_:
        for part in Path(f.name).parts:
            check_name(part, "the texture name")
    gate = Gate(out, WHAT, force=force)
    gate.check(
        [str(p.relative_to(out)) for p in docs] + [f.name for f in copied],
        list(inputs) + [Path(f.source) for f in files_ if f.source],
    )
    pixels = {}
    if files_:
        with files.temporary_folder("ctlab-export-") as scratch:
            for f in files_:
                pixels[f.name] = _decode(f, scratch)
    writers = {f.name: _copy(Path(f.source)) if f.source else _write_bytes(f.data) for f in copied}
    if fmt == "unity":
        writers.update(unity_writers(materials, files_, pixels, out, stem))
    if fmt == "gltf":
        for name, image in metallic_roughness_images(materials, pixels).items():
            writers[name] = _png(image, out / name)
    for path, doc in docs.items():
        text = files.json_text(doc) if isinstance(doc, dict) else doc
        writers[str(path.relative_to(out))] = _write_bytes(text.encode("utf-8"))
    return gate.write(writers, list(inputs) + [Path(f.source) for f in files_ if f.source])


def metallic_roughness_images(materials: list, pixels: dict) -> dict:
    """glTF's packed metallic-roughness images (core.export.maps.metallic_roughness_pixels),
    name -> pixels, from the maps' decoded pixels: the maps themselves are not written into
    the folder, which does not reference them."""
    images = {}
    for mat in materials:
        name = gltf.metallic_roughness_name(mat, materials)
        if name is None:
            continue
        maps = {  # the inputs' values (core/export/maps.py): smoothness, never roughness
            key: texture_values(pixels[mat.textures[key].file], mat.textures[key])
            for key in ("metallic", "smoothness")
            if key in mat.textures
        }
        images[name] = metallic_roughness_pixels(
            maps.get("metallic"), maps.get("smoothness"), False
        )
    return images


def _not_carried(mat, fmt: str) -> list:
    if fmt == "gltf":
        return gltf.gltf_not_carried(mat)
    if fmt == "unity":
        from ..core.unity import mat as unity_mat

        return unity_mat.unity_not_carried(mat)
    return network.not_carried(mat)


def run_export(blend: Path, fmt: str, out: Path, log=None, force: bool = False) -> dict:
    """Open ``blend`` (never saved), read its Cook-Torrance materials, write the export
    (``force``: replace files of the same names that ctlab did not write)."""
    from ..blender.user_blend import check_blend_file, open_blend

    if fmt not in FORMATS:
        raise UserError(f"unknown --format {fmt!r}; choose one of: {', '.join(FORMATS)}")
    blend = check_blend_file(blend)
    open_blend(blend, log)
    materials, files_, notes = material_export.read_materials()
    if not materials:
        raise UserError(
            f"{blend.name} has no Cook-Torrance material; convert one first (Material "
            "Properties > Cook-Torrance > Principled to Cook-Torrance)"
        )
    stem = safe_name(blend.stem, "export")
    written = write_export(materials, files_, fmt, out, stem, inputs=[blend], force=force)
    return {
        "materials": [
            {
                "name": network.label(m),
                "exact": network.exact(m) and fmt in ("materialx", "usd"),
                "not_carried": _not_carried(m, fmt),
            }
            for m in materials
        ],
        "written": [str(p) for p in written],
        "notes": notes,
    }
