"""report.html of ``ctlab scene``: the model's and Principled's renders of a user's scene,
the difference map, the map of the compared materials, and the table of each material's
measures (jobs/scene_job.py computes them with core/compare.py)."""

from __future__ import annotations

import html
import json
from pathlib import Path

from .files import write_text
from .report import STYLE, fmt_value


def write_scene_report(out: Path, data: dict) -> Path:
    """report.html: model | Principled | difference, the mask map and the material table."""
    model_label = "Cook-Torrance" + (" (converted)" if data["convert"] else "")
    principled_label = "Principled BSDF" + (" (the file's)" if data["convert"] else " (converted)")
    figs = (
        ("model/render.png", model_label),
        ("principled/render.png", principled_label),
        ("diff.png", f"&Delta;E00 (black 0, white &ge; {data['heatmap_max_ciede2000']:g})"),
        ("materials.png", "materials compared (colours below; grey: the others)"),
    )
    row = "".join(
        f"<figure><img src='{src}' alt='{html.escape(src)}'><figcaption>"
        f"{label if label.startswith('&') else html.escape(label)}</figcaption>"
        "</figure>"
        for src, label in figs
    )
    head = (
        "<tr><th></th><th>material</th><th>model</th><th>Principled</th><th>pixels</th>"
        "<th>&Delta;E00 mean</th><th>noise floor &Delta;E00 mean</th>"
        "<th>&Delta;E00 of the mean colour</th><th>&Delta;E00 p95</th><th>luminance model / "
        "Principled</th><th>PSNR (dB)</th><th>notes</th></tr>"
    )
    rows = []
    for e in data["materials"]:
        swatch = "#%02x%02x%02x" % tuple(round(255 * c) for c in e["mask_colour"])
        model = e["model"]
        what = (
            f"{model['implementation']}, G {model['g_model']}, {model['diffuse_model']}, "
            f"energy {model['energy']}, {model['light_transport']}"
        )
        rows.append(
            f"<tr><td style='background:{swatch}'></td><td>{html.escape(e['name'])}</td>"
            f"<td>{html.escape(what)}</td>"
            f"<td>{html.escape(str(e.get('principled_distribution') or ''))}</td>"
            f"<td>{e['pixels']}</td><td>{fmt_value(e['ciede2000_mean'], '.2f')}</td>"
            f"<td>{fmt_value(e.get('noise_floor_ciede2000_mean'), '.2f')}</td>"
            f"<td>{fmt_value(e.get('ciede2000_of_mean'), '.2f')}</td>"
            f"<td>{fmt_value(e['ciede2000_p95'], '.2f')}</td>"
            f"<td>{fmt_value(e['luminance_ratio'], '.4f')}</td>"
            f"<td>{fmt_value(e['psnr_db'], '.2f')}</td>"
            f"<td>{html.escape('; '.join(e['notes']))}</td></tr>"
        )
    o = data["overall"]
    rows.append(
        f"<tr class='all'><td></td><td colspan=3>all compared materials</td>"
        f"<td>{o['pixels']}</td><td>{fmt_value(o['ciede2000_mean'], '.2f')}</td><td></td><td></td>"
        f"<td>{fmt_value(o['ciede2000_p95'], '.2f')}</td>"
        f"<td>{fmt_value(o['luminance_ratio'], '.4f')}</td>"
        f"<td>{fmt_value(o['psnr_db'], '.2f')}</td><td></td></tr>"
    )
    params = {
        k: data[k]
        for k in (
            "blend",
            "scene",
            "camera",
            "width",
            "height",
            "samples",
            "seed",
            "light_transport",
            "convert",
            "osl",
            "view_transform",
            "blender",
            "notes",
        )
    }
    direction = (
        "the file's Principled BSDF materials converted to the Cook-Torrance model, "
        "against the originals"
        if data["convert"]
        else "the file's Cook-Torrance materials against each converted to Principled BSDF"
    )
    outside = data["outside"]
    scene, blend = html.escape(data["scene"]), html.escape(Path(data["blend"]).name)
    page = f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>Cook-Torrance Lab: scene {scene}</title>
{STYLE}<style>figure img {{ width: 360px; max-width: 100%; }}</style></head><body>
<h1>Cook-Torrance Lab: {blend}, scene “{scene}”</h1>
<p>The scene through its camera {html.escape(data['camera'])}, rendered twice with the same
Cycles settings ({data['width']}&times;{data['height']} px, {data['samples']} samples, seed
{data['seed']}, light transport <b>{data['light_transport']}</b>): {direction}. Each
material's pixels are those of its Material Index; &Delta;E00 (CIEDE2000) compares the displayed
colours (render.png, the file's view transform {html.escape(data['view_transform'])}), the
luminance ratio the mean Rec. 709 luminance of the raw values (render.exr). The per-pixel mean
&Delta;E00 includes each pixel's noise: the <i>noise floor</i> is the same mean between
Principled and Principled rendered again with another seed (all of it noise), and the
&Delta;E00 of the mean colour compares each material's mean displayed colour, from which noise
averages out. The two compared renders share their seed, so their noise is partly the same
and cancels: a per-pixel mean below the noise floor is usual. Both sides use the same kind of
Principled: Multiscatter GGX where the model's
energy is compensated, GGX where it is none.</p>
<div class='row'>{row}</div>
<h2>Per material</h2><table>{head}{''.join(rows)}</table>
<p>Elsewhere in the image (other materials and the world, which see the compared materials in
the scene transport): mean &Delta;E00 {fmt_value(outside['ciede2000_mean'], '.2f')} over
{outside['pixels']} pixels. Render times: model {data['render_seconds']['model']:.1f} s,
Principled {data['render_seconds']['principled']:.1f} s.</p>
<h2>Parameters</h2><pre>{html.escape(json.dumps(params, indent=2))}</pre>
</body></html>
"""
    path = Path(out) / "report.html"
    write_text(path, page)
    return path
