"""The BRDF plot's files (``ctlab plot``; docs/model.md "BRDF plots"), from the values of
brdf_plot.assemble: the slices as float EXRs and PNGs (log scale, labelled axes, a colour bar),
the lobes and the directional albedo as SVG, PNG (both drawn by core/figures.py) and CSV, a
composite plot.png for the add-on's Image Editor, and plot.json with the parameters and axes.
Every file of a plot is written under a temporary name and renamed when all are whole
(files.atomic_paths).

plot.json is also the manifest of what the plot wrote: each file's content hash
("sha256"). A later plot into the same folder removes an earlier one's files that it does not
write again only when the file still has the hash that plot recorded; a plot.json ctlab did
not write, or a file changed since, is left alone with a warning (ctlab deletes only what it
wrote)."""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np

from . import brdf_plot as bp
from .brdf_plot import luminance, slice_name
from .errors import UserError
from .files import atomic_paths, json_text, sha256
from .hdri import write_float_exr
from . import figures
from .svg import SvgCanvas


def _units_note(settings) -> str:
    return " (x pi: Unity's units)" if settings.units == "unity" else ""


# ----------------------------------------------------------------------------------------
# CSV


def _csv(header: list, rows) -> str:
    out = io.StringIO()
    out.write(",".join(header) + "\n")
    for row in rows:
        out.write(",".join(f"{x:.9g}" for x in row) + "\n")
    return out.getvalue()


def _suffix(tag: str) -> str:
    return f"[{tag}]" if tag else ""


def albedo_csv(albedos: dict) -> str:
    """θv, then specular, diffuse and total directional albedo (R, G, B) of each variant."""
    header, columns = ["theta_v_deg"], [bp.albedo_angles()]
    for tag, a in albedos.items():
        for part in ("specular", "diffuse", "total"):
            for c, ch in enumerate("rgb"):
                header.append(f"{part}_{ch}{_suffix(tag)}")
                columns.append(a[part][:, c])
    return _csv(header, np.stack(columns, axis=1))


def lobe_csv(lobes: dict) -> str:
    """θl, then f_r (n.l) (R, G, B) at each θv of each variant."""
    header, columns = ["theta_l_deg"], [bp.lobe_angles()]
    for tag, values in lobes.items():
        for i, tv in enumerate(bp.LOBE_VIEW_ANGLES):
            for c, ch in enumerate("rgb"):
                header.append(f"theta_v_{tv:g}_{ch}{_suffix(tag)}")
                columns.append(values[i, :, c])
    return _csv(header, np.stack(columns, axis=1))


# ----------------------------------------------------------------------------------------
# The plot's files


def _check_finite(results: dict) -> None:
    for tag, r in results.items():
        if tag == "labels":
            continue
        arrays = list(r["slice"].values()) + [r["lobe"]] + list(r["albedo"].values())
        if not all(np.isfinite(a).all() for a in arrays):
            raise UserError(
                "the model gave a NaN or infinite value for this plot "
                f"({results['labels'][tag]}); please report it"
            )


def plot_data(settings, results: dict, files: list) -> dict:
    """plot.json: the parameters, the axes and the files."""
    th, td = bp.slice_angles()
    base = results[""]
    return {
        "parameters": settings.describe(),
        "slice": {
            "size": bp.SLICE_SIZE,
            "phi_d_deg": bp.SLICE_PHI_D,
            "column": "theta_h_deg = i + 0.5",
            "row": "theta_d_deg = j + 0.5 (row 0 at the top)",
            "theta_h_deg": th.tolist(),
            "theta_d_deg": td.tolist(),
            "value": "f_r = f_d + f_s (1/sr)" + _units_note(settings),
            "zero_where": "n.l <= 0 or n.v <= 0",
            "max": float(np.max(base["slice"]["f_r"])),
        },
        "lobe": {
            "theta_v_deg": list(bp.LOBE_VIEW_ANGLES),
            "theta_l_deg": {"from": -90.0, "to": 90.0, "steps": bp.LOBE_STEPS},
            "value": "f_r (n.l) (1/sr) in the incidence plane; the mirror direction "
            "at theta_l = -theta_v" + _units_note(settings),
        },
        "albedo": {
            "theta_v_deg": bp.albedo_angles().tolist(),
            "quadrature": {
                "grid": list(bp.ALBEDO_GRID),
                "specular": "GGX half vectors, weight 4 (v.h) / (D (n.h))",
                "diffuse": "cosine-distributed, weight pi / (n.l)",
            },
            "mean_total": float(np.mean(luminance(base["albedo"]["total"]))),
        },
        "variants": [{"tag": tag, "label": label} for tag, label in results["labels"].items()],
        "files": files,
    }


def planned_names(settings) -> set:
    """The names of the files a plot with these settings writes, known before any render
    (so a folder standing where one goes is refused first; write_plot checks it agrees)."""
    tags = [tag for tag, _, _ in settings.variants() if tag]
    slices = (
        [slice_name()] + [slice_name(v) for v in settings.views] + [slice_name(tag=t) for t in tags]
    )
    return (
        {f"{n}.exr" for n in slices}
        | {f"{n}.png" for n in slices}
        | {slice_name(tag=f"diff_{t}") + ".png" for t in tags}
        | {
            "lobe.svg",
            "albedo.svg",
            "lobe.csv",
            "albedo.csv",
            "lobe.png",
            "albedo.png",
            "plot.png",
            "plot.json",
        }
    )


def refuse_blocked(out: Path, names) -> None:
    """A folder (or anything not a file) where the plot writes a file is refused."""
    out = Path(out)
    blocked = sorted(n for n in names if (out / n).exists() and not (out / n).is_file())
    if blocked:
        raise UserError(
            f"{out} holds a folder named {blocked[0]}, where the plot writes a "
            "file; choose another --out"
        )


def write_plot(out: Path, settings, results: dict, extra: dict | None = None, warn=None) -> dict:
    """Every file of the plot, written together (whole or not at all); returns plot.json's
    data (with ``extra``, e.g. the Blender version, under "renderer"). ``warn(message)``:
    an earlier plot's file that is left alone (not verifiably ctlab's)."""
    _check_finite(results)
    out = Path(out)
    tags = [t for t in results if t != "labels"]
    base = results[""]
    exrs = {slice_name(): base["slice"]["f_r"]}
    exrs.update({slice_name(view): base["slice"][view] for view in settings.views})
    exrs.update({slice_name(tag=tag): results[tag]["slice"]["f_r"] for tag in tags if tag})
    lobes = {tag: results[tag]["lobe"] for tag in tags}
    albedos = {tag: results[tag]["albedo"] for tag in tags}
    title = f"metallic {settings.metallic:.3g}, smoothness {settings.smoothness:.3g}" + _units_note(
        settings
    )
    texts = {
        f"{name}.svg": c.svg()
        for name, c in figures.curve_figures(results, title, canvas=SvgCanvas).items()
    }
    texts.update({"lobe.csv": lobe_csv(lobes), "albedo.csv": albedo_csv(albedos)})
    pngs = figures.figures(settings, results, title)
    names = [f"{n}.exr" for n in exrs] + list(texts) + list(pngs) + ["plot.json"]
    data = plot_data(settings, results, names)
    if extra:
        data["renderer"] = extra
    paths = [out / n for n in names]
    refuse_blocked(out, names)
    earlier, unverified = _earlier_files(out, set(names))
    with atomic_paths(*paths) as staged:  # renamed in order: plot.json, the index, last
        where = dict(zip(names, staged))
        for n, values in exrs.items():
            write_float_exr(where[f"{n}.exr"], values)
        for n, text in texts.items():
            where[n].write_text(text, encoding="utf-8")
        for n, canvas in pngs.items():
            canvas.save_png(where[n])
        data["sha256"] = {n: sha256(where[n]) for n in names if n != "plot.json"}
        where["plot.json"].write_text(json_text(data), encoding="utf-8")
    for name in earlier:  # an earlier plot's variants and views
        (out / name).unlink(missing_ok=True)
    if unverified and warn is not None:
        warn(
            f"{len(unverified)} file(s) an earlier plot.json in {out} lists were left alone "
            f"(not verifiably written by ctlab: {', '.join(sorted(unverified)[:3])})"
        )
    return data


def _earlier_files(out: Path, keep: set) -> tuple:
    """The files an earlier plot in ``out`` wrote and this one does not write again, as two
    sets: those that still hold the content hash its plot.json recorded (safe to remove),
    and those listed without a matching hash (left alone: a plot.json ctlab did not write, or
    edited, or a file changed since). Plain names of regular files only."""
    import json
    import os
    import stat

    try:
        data = json.loads((out / "plot.json").read_text(encoding="utf-8"))
        files, hashes = data["files"], data.get("sha256", {})
    except (OSError, ValueError, KeyError, TypeError, AttributeError):
        return set(), set()
    if not isinstance(files, list) or not isinstance(hashes, dict):
        return set(), set()
    ours, others = set(), set()
    for f in files:
        if not isinstance(f, str) or f != Path(f).name or f in (".", "..") or f in keep:
            continue
        try:
            if not stat.S_ISREG(os.lstat(out / f).st_mode):
                continue
        except OSError:
            continue
        recorded = hashes.get(f)
        (ours if isinstance(recorded, str) and recorded == sha256(out / f) else others).add(f)
    return ours, others
