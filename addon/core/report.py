"""report.html of the main job and of the parity job. The main job's: each comparison as
render | reference | difference with per-cell numbers laid out as the matrix (the model
against Principled BSDF, the baked IBL modes against the reference integration, the node group
against the OSL shader), the attribution table, the white-furnace plot, the timings and the
parameters. The parity job's: each HDRI's comparison against its bound."""

from __future__ import annotations

import html
import json
from pathlib import Path

from .files import write_text


def _table(metrics: dict) -> str:
    rows = []
    for c in metrics["cells"]:
        rows.append(
            f"<tr><td>{c['row']}</td><td>{c['col']}</td><td>{c['metallic']:.3f}</td>"
            f"<td>{c['smoothness']:.3f}</td><td>{c['mae']:.4f}</td><td>{c['rmse']:.4f}</td>"
            f"<td>{fmt_value(c['rel_luminance_error'], '+.1%')}</td>"
            f"<td>{fmt_value(c['psnr_db'], '.2f')}</td><td>{c['ciede2000_mean']:.2f}</td>"
            f"<td>{c['ciede2000_p95']:.2f}</td></tr>"
        )
    o = metrics["overall"]
    rows.append(
        f"<tr class='all'><td colspan=4>all cells</td><td>{o['mae']:.4f}</td>"
        f"<td>{o['rmse']:.4f}</td><td>{fmt_value(o['rel_luminance_error'], '+.1%')}</td>"
        f"<td>{fmt_value(o['psnr_db'], '.2f')}</td>"
        f"<td>{o['ciede2000_mean']:.2f}</td><td>{o['ciede2000_p95']:.2f}</td></tr>"
    )
    head = (
        "<tr><th>row</th><th>col</th><th>metallic</th><th>smoothness</th><th>MAE</th>"
        "<th>RMSE</th><th>rel. luminance</th><th>PSNR (dB)</th><th>&Delta;E00 mean</th>"
        "<th>&Delta;E00 p95</th></tr>"
    )
    return f"<table>{head}{''.join(rows)}</table>"


def fmt_value(value, fmt: str) -> str:
    """A number for a table cell; None as a dash."""
    return "&ndash;" if value is None else format(value, fmt)


def _grid(metrics: dict, key: str, fmt: str) -> str:
    """The per-cell metric laid out as the sphere matrix."""
    cells = metrics["cells"]
    rows = max(c["row"] for c in cells) + 1
    cols = max(c["col"] for c in cells) + 1
    value = {(c["row"], c["col"]): c[key] for c in cells}
    smooth = {c["row"]: c["smoothness"] for c in cells}
    metal = {c["col"]: c["metallic"] for c in cells}
    head = (
        "<tr><th>smoothness \\ metallic</th>"
        + "".join(f"<th>{metal[j]:.2f}</th>" for j in range(cols))
        + "</tr>"
    )
    body = "".join(
        "<tr><th>"
        + f"{smooth[i]:.2f}</th>"
        + "".join(f"<td>{fmt_value(value[(i, j)], fmt)}</td>" for j in range(cols))
        + "</tr>"
        for i in range(rows)
    )
    return f"<table class='grid'>{head}{body}</table>"


def _figures(a_dir, b_dir, cmp_dir, a_label, b_label, metrics) -> str:
    figs = (
        (f"{a_dir}/render.png", a_label),
        (f"{b_dir}/render.png", b_label),
        (
            f"{cmp_dir}/diff.png",
            f"&Delta;E00 (black 0, white &ge; {metrics['heatmap_max_ciede2000']:g})",
        ),
    )
    return (
        "<div class='row'>"
        + "".join(
            f"<figure><img src='{html.escape(src)}' alt='{html.escape(label)}'>"
            f"<figcaption>{label if label.startswith('&') else html.escape(label)}"
            "</figcaption></figure>"
            for src, label in figs
        )
        + "</div>"
    )


def _summary(metrics: dict) -> str:
    o = metrics["overall"]
    return (
        f"Over all sphere pixels: mean &Delta;E00 <b>{o['ciede2000_mean']:.2f}</b> "
        f"(95th percentile {o['ciede2000_p95']:.2f}), PSNR {fmt_value(o['psnr_db'], '.2f')} dB "
        f"(displayed "
        f"colours), relative luminance error {fmt_value(o['rel_luminance_error'], '+.1%')}, MAE "
        f"{o['mae']:.4f} and RMSE {o['rmse']:.4f} (linear values)."
    )


SPLIT_SUM_NOTE = """<p>The split-sum (Karis 2013) replaces the integral of f_r L (n.l) by two
factors: the environment pre-filtered with the GGX lobe under the assumption n = v = r, and the
BRDF's directional albedo (the DFG table, integrated for this model's D and G). It is exact for a
uniform environment; elsewhere it errs most at grazing views, where the true lobe is stretched
and bent toward the normal while the pre-filtered lobe stays round around r, and on rough
surfaces under a small bright source (the sun), whose highlight it centres on r. The Unity mode
adds Unity's own shortcuts: its mip mapping of roughness, surfaceReduction and FresnelLerp in
place of the DFG table, and no Disney factor on indirect diffuse. The node group computes the
same split-sum as the OSL shader from the same files, but cannot trace the Sun's shadow: it
differs where one sphere shadows another.</p>"""


ATTRIBUTION_NOTE = """<p>Each row switches one model choice toward Principled BSDF and shows
the mean &Delta;E00 against Principled that is left; a drop is the share of the difference that
choice explains. G: the seed's Cook-Torrance G against the height-correlated Smith G Principled
uses. Diffuse: Disney against Lambert. Multiple scattering: the last step compares with
Principled's single-scatter GGX instead of its default Multiscatter GGX, which adds back the
energy single scattering loses on rough metals. What is left after all three is Principled's
energy-conserving layering (its diffuse is weighted by what the specular layer does not
reflect, where the model uses the fixed 1 - 0.04 of Unity), its dielectric Fresnel (IOR 1.5
against Schlick at F0 = 0.04), and render noise. Its renders, the seed model and Principled
included, are 3/8 of the main render's size (its spheres kept at least 3 px across their radius;
each folder's scene.json has the size): the same samples per pixel on a seventh of the pixels,
so its per-sphere means keep their meaning, and its first row is close to, not equal to, the
comparison above.</p>"""

FURNACE_NOTE = """<p>White furnace: a uniform world of radiance 1, the Sun off, metallic 1 and
albedo 1 (so F = 1): the indirect_specular view is the specular directional albedo, which
energy conservation bounds by 1. Single-scattering microfacet BRDFs lose energy at high
roughness (light that would scatter again between microfacets is dropped). Smith's G loses
more than the Cook-Torrance (V-cavity) G, min(1, 2(n.h)(n.v)/(v.h), 2(n.h)(n.l)/(v.h)), whose
masking is weaker at grazing views (Heitz 2014, section 5): with this model's GGX D the
Cook-Torrance G keeps more energy on rough surfaces, most at grazing views, and both stay
below 1 (brute-force quadrature of the model's formulas agrees; tests/slow/test_energy.py). With
energy compensated (Turquin 2019's albedo scaling with Kulla and Conty's Fresnel term, as
Cycles compensates Principled's GGX) the lobe reflects everything: the dotted curves sit at 1.
Solid: the first set; dashed: the second; dotted: the third. Curves are measured from the
renders (pixels binned by view angle, n.v from each pixel's place on the sphere).</p>"""


def attribution_table(steps) -> str:
    """``steps``: (label, metrics[, the step it follows]) in switch order, the first the seed
    model; a step follows the one before it unless it says which. Per cell, the mean CIEDE2000
    left after each switch (and its change from the step it follows), and the overall means."""
    cells = steps[0][1]["cells"]
    after = [step[2] if len(step) > 2 else k - 1 for k, step in enumerate(steps)]
    head = (
        "<tr><th>metallic</th><th>smoothness</th>"
        + "".join(f"<th>{html.escape(step[0])}</th>" for step in steps)
        + "</tr>"
    )

    def row(values):
        return "".join(
            f"<td>{v:.2f}" + (f" ({v - values[after[k]]:+.2f})" if k else "") + "</td>"
            for k, v in enumerate(values)
        )

    rows = []
    for i, c in enumerate(cells):
        values = [step[1]["cells"][i]["ciede2000_mean"] for step in steps]
        rows.append(
            f"<tr><td>{c['metallic']:.2f}</td><td>{c['smoothness']:.2f}</td>"
            + row(values)
            + "</tr>"
        )
    overall = [step[1]["overall"]["ciede2000_mean"] for step in steps]
    rows.append("<tr class='all'><td colspan=2>all cells</td>" + row(overall) + "</tr>")
    return f"<table>{head}{''.join(rows)}</table>"


def furnace_section(furnace: dict) -> str:
    from .energy import mean_albedo
    from .figures import furnace_figure

    head = (
        "<tr><th>smoothness</th>"
        + "".join(f"<th>{html.escape(g)}: mean</th><th>max</th>" for g in furnace)
        + "</tr>"
    )
    rows = []
    curves = list(furnace.values())
    for i, c in enumerate(curves[0]):
        cells = "".join(
            f"<td>{mean_albedo(cs[i]):.3f}</td>"
            f"<td>{max(x for x in cs[i]['albedo'] if x is not None):.3f}</td>"
            for cs in curves
        )
        rows.append(f"<tr><td>{c['smoothness']:.2f}</td>{cells}</tr>")
    return (
        f"<h2>Energy: white furnace</h2>{FURNACE_NOTE}{furnace_figure(furnace).svg()}"
        f"<table>{head}{''.join(rows)}</table>"
    )


PLOTS_NOTE = """<p>The BRDF itself, evaluated by the OSL shader's own code at one configuration
per pixel (<code>ctlab plot</code>, docs/model.md "BRDF plots"), for up to four spheres of this
job (a smooth and a rough metal and dielectric): the &theta;<sub>h</sub> &times;
&theta;<sub>d</sub> slice of f<sub>r</sub> = f<sub>d</sub> + f<sub>s</sub> at
&phi;<sub>d</sub> = 90&deg; (Burley 2012; log scale, 7 decades below the maximum) for this
model and for the other G models, and each one's relative difference from this model (red:
the other G gives more, blue: less); then the lobes f<sub>r</sub> (n&middot;l) in the
incidence plane (a colour per view angle; solid this model, dashed and dotted the other G
models) and the directional albedo (a colour per G model; solid the total, dashed the
specular part, dotted the diffuse part). At &phi;<sub>d</sub> = 90&deg; the Cook-Torrance G,
min(1, 2(n&middot;h)(n&middot;v)/(v&middot;h), 2(n&middot;h)(n&middot;l)/(v&middot;h)), is
min(1, 2 cos&sup2;&theta;<sub>h</sub>): 1 up to &theta;<sub>h</sub> = 45&deg; whatever
&theta;<sub>d</sub>, where Smith's G falls toward grazing &theta;<sub>d</sub> (blue in the
difference slices), and below 1 beyond 45&deg;, where Smith's is larger at small
&theta;<sub>d</sub> (red). A dielectric's total albedo can exceed 1 at grazing views: the
model's diffuse is the fixed 0.96 &times; albedo of Unity's Standard shader, not reduced where
the specular's Fresnel term grows.</p>"""


def plots_section(plots) -> str:
    """``plots``: (label, folder, plot.json data) per sphere."""
    from .brdf_plot import slice_name

    parts = ["<h2>The BRDF itself: slices, lobes and directional albedo</h2>", PLOTS_NOTE]
    for label, folder, data in plots:
        variants = data["variants"]
        figs = [(slice_name(), f"f_r: {variants[0]['label']}")]
        figs += [(slice_name(tag=v["tag"]), f"f_r: {v['label']}") for v in variants[1:]]
        figs += [
            (slice_name(tag=f"diff_{v['tag']}"), f"({v['label']} &minus; this) / this")
            for v in variants[1:]
        ]
        row = "".join(
            f"<figure class='plot'><img src='{html.escape(folder)}/{name}.png' "
            f"alt='{html.escape(name)}'><figcaption>"
            f"{caption if '&' in caption else html.escape(caption)}"
            f"</figcaption></figure>"
            for name, caption in figs
        )
        curves = "".join(
            f"<figure><img src='{html.escape(folder)}/{name}' alt='{name}'></figure>"
            for name in ("lobe.svg", "albedo.svg")
        )
        parts.append(
            f"<h3>{html.escape(label)}</h3><div class='row'>{row}</div>"
            f"<div class='row'>{curves}</div>"
        )
    return "".join(parts)


STYLE = """<style>
body { font-family: system-ui, sans-serif; margin: 2em; color: #222; }
.row { display: flex; gap: 1em; flex-wrap: wrap; }
figure { margin: 0; } figure img { width: 100%; max-width: 512px; image-rendering: pixelated; }
figcaption { text-align: center; font-weight: 600; }
figure.plot img { max-width: 340px; image-rendering: auto; }
table { border-collapse: collapse; margin: 1em 0; font-size: 0.9em; }
td, th { border: 1px solid #ccc; padding: 2px 8px; text-align: right; }
tr.all td { font-weight: 600; } pre { background: #f4f4f4; padding: 1em; }
</style>"""


def textures_section(textures: dict | None) -> str:
    """The albedo texture and normal map the spheres wore (core/textures.py), shown small,
    or "" when the job had none."""
    from .textures import thumbnail_uri

    shown = [
        (label, textures.get(key))
        for key, label in (("albedo_texture", "Albedo texture"), ("normal_map", "Normal map"))
        if textures and textures.get(key)
    ]
    if not shown:
        return ""
    figures = "".join(
        f"<figure><img src='{thumbnail_uri(path)}' alt='{html.escape(label)}' style='width:160px'>"
        f"<figcaption>{html.escape(label)}: {html.escape(str(path))}</figcaption></figure>"
        for label, path in shown
    )
    strength = textures.get("normal_strength", 1.0)
    return (
        "<h2>Textures: on</h2><p>Every sphere, the model's and Principled's alike, wears "
        f"{' and '.join(label.lower() for label, _ in shown)} below (the UV sphere's UVs, "
        "repeated twice around and once from pole to pole; the normal map in OpenGL "
        f"convention through Blender's Normal Map node, strength {strength:g}). The term "
        "views shade the perturbed normal.</p>"
        f"<div class='row'>{figures}</div>"
    )


def _write(out_dir: Path, page: str) -> Path:
    """report.html, whole or not at all."""
    path = Path(out_dir) / "report.html"
    write_text(path, page)
    return path


PARITY_NOTE = """<p>With G = height-correlated Smith, Lambert diffuse, metallic 1 (so the
diffuse term is zero and F is Schlick on the albedo), the Sun off and no sphere shadowing
another, the model's BRDF is the one Principled BSDF uses for a metal with its single-scatter
GGX distribution (its F82 tint is Schlick when Specular Tint is white). Our reference
integration (importance-sampled environment and BRDF, MIS) and Cycles' path tracer then
estimate the same integral: what differs is noise.</p>"""


def write_parity_report(out_dir: Path, entries, bound: float) -> Path:
    """``entries``: (HDRI name, metrics, scene) per HDRI; folders <name>/cook_torrance,
    <name>/principled, <name>/compare."""
    sections = []
    for name, metrics, scene in entries:
        worst = max(c["ciede2000_mean"] for c in metrics["cells"])
        verdict = "holds" if worst <= bound else "FAILS"
        sections.append(
            f"<h2>{html.escape(name)}: parity {verdict} (worst sphere {worst:.2f}, bound "
            f"{bound:g})</h2>"
            + _figures(
                f"{name}/cook_torrance",
                f"{name}/principled",
                f"{name}/compare",
                "Cook-Torrance (Smith, Lambert, reference IBL)",
                "Principled BSDF (GGX)",
                metrics,
            )
            + f"<p>{_summary(metrics)} {scene.get('samples', '?')} samples per pixel.</p>"
            + f"<h3>Mean &Delta;E00 per sphere</h3>{_grid(metrics, 'ciede2000_mean', '.2f')}"
            + "<h3>Relative luminance error per sphere</h3>"
            + _grid(metrics, 'rel_luminance_error', '+.1%')
        )
    page = f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>Cook-Torrance Lab: Principled parity</title>
{STYLE}</head><body>
<h1>Cook-Torrance Lab: Principled parity</h1>{PARITY_NOTE}{''.join(sections)}
</body></html>
"""
    return _write(out_dir, page)


def write_report(
    out_dir: Path,
    comparisons,
    scene: dict,
    timings: dict,
    attribution=None,
    furnace=None,
    plots=None,
) -> Path:
    """Write report.html into out_dir (whole or not at all); image paths are relative.

    ``comparisons``: (render folder, reference folder, comparison folder, render label,
    reference label, metrics) tuples; the first is the model against Principled BSDF.
    ``attribution``: (switch label, metrics against Principled) in switch order;
    ``furnace``: {curve set label: energy.directional_albedo curves}; ``plots``: (label,
    folder, plot.json data) of the BRDF plots."""
    params = {
        k: scene[k]
        for k in (
            "rows",
            "cols",
            "width",
            "height",
            "samples",
            "hdri",
            "hdri_strength",
            "hdri_rotation_deg",
            "sun",
            "model",
            "principled_distribution",
            "textures",
            "blender",
        )
        if k in scene
    }
    main, studies = comparisons[0], comparisons[1:]
    metrics = main[5]
    study_html = ""
    if studies:
        study_html = (
            "<h2>Baked IBL against the reference integration; the node group against "
            "the OSL shader</h2>" + SPLIT_SUM_NOTE
        )
        for a_dir, b_dir, cmp_dir, a_label, b_label, m in studies:
            study_html += (
                f"<h3>{html.escape(a_label)} against {html.escape(b_label)}</h3>"
                f"{_figures(a_dir, b_dir, cmp_dir, a_label, b_label, m)}"
                f"<p>{_summary(m)}</p>"
                f"<h4>Mean &Delta;E00 per cell</h4>{_grid(m, 'ciede2000_mean', '.2f')}"
                f"<h4>Relative luminance error per cell (positive: brighter than the "
                f"reference)</h4>{_grid(m, 'rel_luminance_error', '+.1%')}"
            )
    page = f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>Cook-Torrance Lab: sphere matrix report</title>
{STYLE}</head><body>
<h1>Cook-Torrance Lab: sphere matrix</h1>
<p>Columns: metallic 0 &rarr; 1 (left to right). Rows: smoothness 1 &rarr; 0 (top to bottom).
All renders use the same world HDRI and Sun; the Cook-Torrance renders are the OSL shader
(docs/model.md), the reference is Blender's Principled BSDF path-traced by Cycles.</p>
{_figures(*main)}
{textures_section(scene.get("textures"))}
<h2>Summary</h2>
<p>{_summary(metrics)} Render times: {
        html.escape(', '.join(f'{k} {v:.1f} s' for k, v in timings.items()))
    }.</p>
<p>Differences are expected: the seed model uses the Cook-Torrance G and Disney diffuse, with
no multiple scattering, while Principled uses height-correlated Smith G, multiscatter GGX and
energy-conserving layering.</p>
<h2>Mean &Delta;E00 per cell</h2>{_grid(metrics, 'ciede2000_mean', '.2f')}
<h2>Per-cell metrics</h2>{_table(metrics)}
<p>MAE and RMSE compare the raw float values (render.exr); PSNR and &Delta;E00 (CIEDE2000)
compare the displayed colours (render.png, AgX view transform); the relative luminance error
compares the mean Rec. 709 luminance of the raw values. Cells use the pixels within 95% of
each sphere's radius.</p>
{
        "<h2>Attribution: what explains the difference from Principled</h2>"
        + ATTRIBUTION_NOTE
        + attribution_table(attribution)
        if attribution
        else ""
    }
{furnace_section(furnace) if furnace else ""}
{plots_section(plots) if plots else ""}
{study_html}
<h2>Parameters</h2><pre>{html.escape(json.dumps(params, indent=2))}</pre>
</body></html>
"""
    return _write(out_dir, page)
