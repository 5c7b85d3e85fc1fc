"""The BRDF plot's files (``ctlab plot``; docs/model.md "BRDF plots"), from the values of
brdf_plot.assemble: the slices as float EXRs and PNGs (log scale, labelled axes, a colour bar),
the lobes and the directional albedo as SVG, PNG and CSV, a composite plot.png for the
add-on's Image Editor, and plot.json with the parameters and axes. Every file of a plot is
written under a temporary name and renamed when all are whole (files.atomic_paths).

plot.json is also the manifest of what the plot wrote: each file's content hash
("sha256"). A later plot into the same folder removes an earlier one's files that it does not
write again only when the file still has the hash that plot recorded; a plot.json ctlab did
not write, or a file changed since, is left alone with a warning (ctlab deletes only what it
wrote)."""

from __future__ import annotations

import html
import io
import math
from pathlib import Path

import numpy as np

from . import brdf_plot as bp
from .brdf_plot import luminance, slice_name
from .errors import UserError
from .files import atomic_paths, json_text
from .hdri import write_float_exr
from . import raster_figures, svg
from .svg import COLOURS, DASHES


def _units_note(settings) -> str:
    return " (x pi: Unity's units)" if settings.units == "unity" else ""


# ----------------------------------------------------------------------------------------
# SVG

def _dash(k: int) -> str:
    pattern = DASHES[k % len(DASHES)]
    return f" stroke-dasharray='{' '.join(map(str, pattern))}'" if pattern else ""


def lobe_svg(lobes: dict, labels: dict, title: str = "", width: int = 640,
             height: int = 420) -> str:
    """f_r (n.l) (luminance) in the incidence plane as polar curves: the normal up, θl from
    -90° (left) to 90° (right), one colour per view angle θv, one dash pattern per variant
    (``lobes``: {tag: (len(θv), steps, 3)}). The radius is linear, 1 at the largest value."""
    theta_l = np.radians(bp.lobe_angles())
    peak = max(float(np.max(luminance(v))) for v in lobes.values()) or 1.0
    cx, cy, r = width / 2, height - 60, min(width / 2 - 40, height - 110)
    parts = svg.document(width, height)
    for f in (0.25, 0.5, 0.75, 1.0):
        parts.append(f"<path d='M {cx - r * f:.1f} {cy} A {r * f:.1f} {r * f:.1f} 0 0 1 "
                     f"{cx + r * f:.1f} {cy}' fill='none' stroke='#ddd'/>"
                     f"<text x='{cx + r * f - 2:.1f}' y='{cy + 13}' fill='#666' "
                     f"text-anchor='end'>{raster_figures.number(peak * f)}</text>")
    for deg in range(-90, 91, 30):
        a = math.radians(deg)
        x, y = cx + r * math.sin(a), cy - r * math.cos(a)
        parts.append(f"<line x1='{cx}' y1='{cy}' x2='{x:.1f}' y2='{y:.1f}' stroke='#eee'/>"
                     f"<text x='{cx + (r + 14) * math.sin(a):.1f}' "
                     f"y='{cy - (r + 14) * math.cos(a) + 4:.1f}' text-anchor='middle' "
                     f"fill='#666'>{deg}&#176;</text>")
    parts.append(f"<line x1='{cx - r - 10}' y1='{cy}' x2='{cx + r + 10}' y2='{cy}' "
                 "stroke='#444'/>")
    for i, tv in enumerate(bp.LOBE_VIEW_ANGLES):
        a = math.radians(tv)
        colour = COLOURS[i % len(COLOURS)]
        parts.append(f"<line x1='{cx}' y1='{cy}' x2='{cx + 0.18 * r * math.sin(a):.1f}' "
                     f"y2='{cy - 0.18 * r * math.cos(a):.1f}' stroke='{colour}' "
                     "stroke-width='2.5'/>")
        for k, (tag, values) in enumerate(lobes.items()):
            rho = luminance(values[i]) / peak
            pts = " ".join(f"{cx + r * q * math.sin(t):.1f},{cy - r * q * math.cos(t):.1f}"
                           for t, q in zip(theta_l, rho))
            parts.append(f"<polyline points='{pts}' fill='none' stroke='{colour}' "
                         f"stroke-width='1.6'{_dash(k)}/>")
    y = 18
    if title:
        parts.append(f"<text x='10' y='{y}' font-size='13' font-weight='600'>"
                     f"{html.escape(title)}</text>")
        y += 18
    for i, tv in enumerate(bp.LOBE_VIEW_ANGLES):
        parts.append(f"<line x1='10' y1='{y - 4}' x2='30' y2='{y - 4}' "
                     f"stroke='{COLOURS[i % len(COLOURS)]}' stroke-width='2.5'/>"
                     f"<text x='36' y='{y}'>&#952;v = {tv:g}&#176;</text>")
        y += 15
    y = 18
    for k, tag in enumerate(lobes):
        parts.append(f"<line x1='{width - 260}' y1='{y - 4}' x2='{width - 235}' y2='{y - 4}' "
                     f"stroke='#333' stroke-width='1.6'{_dash(k)}/>"
                     f"<text x='{width - 230}' y='{y}'>{html.escape(labels[tag])}</text>")
        y += 15
    parts.append(f"<text x='{cx}' y='{height - 12}' text-anchor='middle' fill='#444'>"
                 "f_r (n.l), luminance, in the incidence plane; radius linear, "
                 f"outer ring {raster_figures.number(peak)}</text></svg>")
    return "".join(parts)


def albedo_svg(albedos: dict, labels: dict, title: str = "", width: int = 700,
               height: int = 320) -> str:
    """Directional albedo (luminance) against θv: solid total, dashed specular, dotted
    diffuse; one colour per variant (``albedos``: {tag: {"specular"|"diffuse"|"total":
    (len(θv), 3)}})."""
    tv = bp.albedo_angles()
    top_value = max(1.0, max(float(np.max(luminance(a["total"]))) for a in albedos.values()))
    y_max = math.ceil(top_value * 10 + 0.5) / 10
    left, right, top, bottom = 48, 270, 28 if title else 12, 36
    pw, ph = width - left - right, height - top - bottom

    parts = svg.document(width, height)
    if title:
        parts.append(f"<text x='10' y='18' font-size='13' font-weight='600'>"
                     f"{html.escape(title)}</text>")
    xy = svg.view_angle_axes(parts, (left, top, pw, ph), height, y_max,
                             "directional albedo (luminance)")
    styles = (("total", ""), ("specular", " stroke-dasharray='6 3'"),
              ("diffuse", " stroke-dasharray='2 2'"))
    y = top + 10
    for k, (tag, a) in enumerate(albedos.items()):
        colour = COLOURS[k % len(COLOURS)]
        for part, dash in styles:
            pts = " ".join("%.1f,%.1f" % xy(t, e) for t, e in zip(tv, luminance(a[part])))
            parts.append(f"<polyline points='{pts}' fill='none' stroke='{colour}' "
                         f"stroke-width='1.6'{dash}/>")
        parts.append(svg.legend_entry(left + pw + 10, y + 4, labels[tag], colour))
        y += 15
    for part, dash in styles:
        parts.append(svg.legend_entry(left + pw + 10, y + 10, part, dash=dash, width=1.6))
        y += 15
    parts.append("</svg>")
    return "".join(parts)


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
            raise UserError("the model gave a NaN or infinite value for this plot "
                            f"({results['labels'][tag]}); please report it")


def plot_data(settings, results: dict, files: list) -> dict:
    """plot.json: the parameters, the axes and the files."""
    th, td = bp.slice_angles()
    base = results[""]
    return {
        "parameters": settings.describe(),
        "slice": {"size": bp.SLICE_SIZE, "phi_d_deg": bp.SLICE_PHI_D,
                  "column": "theta_h_deg = i + 0.5", "row": "theta_d_deg = j + 0.5 (row 0 "
                  "at the top)", "theta_h_deg": th.tolist(), "theta_d_deg": td.tolist(),
                  "value": "f_r = f_d + f_s (1/sr)" + _units_note(settings),
                  "zero_where": "n.l <= 0 or n.v <= 0",
                  "max": float(np.max(base["slice"]["f_r"]))},
        "lobe": {"theta_v_deg": list(bp.LOBE_VIEW_ANGLES),
                 "theta_l_deg": {"from": -90.0, "to": 90.0, "steps": bp.LOBE_STEPS},
                 "value": "f_r (n.l) (1/sr) in the incidence plane; the mirror direction "
                          "at theta_l = -theta_v" + _units_note(settings)},
        "albedo": {"theta_v_deg": bp.albedo_angles().tolist(),
                   "quadrature": {"grid": list(bp.ALBEDO_GRID),
                                  "specular": "GGX half vectors, weight 4 (v.h) / (D (n.h))",
                                  "diffuse": "cosine-distributed, weight pi / (n.l)"},
                   "mean_total": float(np.mean(luminance(base["albedo"]["total"])))},
        "variants": [{"tag": tag, "label": label} for tag, label in results["labels"].items()],
        "files": files,
    }


def planned_names(settings) -> set:
    """The names of the files a plot with these settings writes, known before any render
    (so a folder standing where one goes is refused first; write_plot checks it agrees)."""
    tags = [tag for tag, _, _ in settings.variants() if tag]
    slices = [slice_name()] + [slice_name(v) for v in settings.views] + \
        [slice_name(tag=t) for t in tags]
    return ({f"{n}.exr" for n in slices} | {f"{n}.png" for n in slices}
            | {slice_name(tag=f"diff_{t}") + ".png" for t in tags}
            | {"lobe.svg", "albedo.svg", "lobe.csv", "albedo.csv", "lobe.png", "albedo.png",
               "plot.png", "plot.json"})


def refuse_blocked(out: Path, names) -> None:
    """A folder (or anything not a file) where the plot writes a file is refused."""
    out = Path(out)
    blocked = sorted(n for n in names if (out / n).exists() and not (out / n).is_file())
    if blocked:
        raise UserError(f"{out} holds a folder named {blocked[0]}, where the plot writes a "
                        "file; choose another --out")


def write_plot(out: Path, settings, results: dict, extra: dict | None = None,
               warn=None) -> dict:
    """Every file of the plot, written together (whole or not at all); returns plot.json's
    data (with ``extra``, e.g. the Blender version, under "renderer"). ``warn(message)``:
    an earlier plot's file that is left alone (not verifiably ctlab's)."""
    _check_finite(results)
    out = Path(out)
    tags = [t for t in results if t != "labels"]
    labels = results["labels"]
    base = results[""]
    exrs = {slice_name(): base["slice"]["f_r"]}
    exrs.update({slice_name(view): base["slice"][view] for view in settings.views})
    exrs.update({slice_name(tag=tag): results[tag]["slice"]["f_r"] for tag in tags if tag})
    lobes = {tag: results[tag]["lobe"] for tag in tags}
    albedos = {tag: results[tag]["albedo"] for tag in tags}
    title = (f"metallic {settings.metallic:.3g}, smoothness {settings.smoothness:.3g}"
             + _units_note(settings))
    texts = {"lobe.svg": lobe_svg(lobes, labels, "Lobes: " + title),
             "albedo.svg": albedo_svg(albedos, labels, "Directional albedo: " + title),
             "lobe.csv": lobe_csv(lobes), "albedo.csv": albedo_csv(albedos)}
    pngs = raster_figures.figures(settings, results, title)
    names = [f"{n}.exr" for n in exrs] + list(texts) + list(pngs) + ["plot.json"]
    data = plot_data(settings, results, names)
    if extra:
        data["renderer"] = extra
    paths = [out / n for n in names]
    refuse_blocked(out, names)
    earlier, unverified = _earlier_files(out, set(names))
    with atomic_paths(*paths) as staged:      # renamed in order: plot.json, the index, last
        where = dict(zip(names, staged))
        for n, values in exrs.items():
            write_float_exr(where[f"{n}.exr"], values)
        for n, text in texts.items():
            where[n].write_text(text, encoding="utf-8")
        for n, canvas in pngs.items():
            canvas.save_png(where[n])
        data["sha256"] = {n: _digest(where[n]) for n in names if n != "plot.json"}
        where["plot.json"].write_text(json_text(data), encoding="utf-8")
    for name in earlier:                      # an earlier plot's variants and views
        (out / name).unlink(missing_ok=True)
    if unverified and warn is not None:
        warn(f"{len(unverified)} file(s) an earlier plot.json in {out} lists were left alone "
             f"(not verifiably written by ctlab: {', '.join(sorted(unverified)[:3])})")
    return data


def _digest(path: Path) -> str:
    import hashlib
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


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
        (ours if isinstance(recorded, str) and recorded == _digest(out / f) else others).add(f)
    return ours, others
