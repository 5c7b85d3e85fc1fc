"""Every figure the project draws, each drawn once (the one figure module): the BRDF plot's
slices as heat maps with labelled θh and θd axes and a colour bar (log scale for the
BRDF-valued views), each variant's relative difference from the plot's model, the lobes, the
directional albedo, plot.png (the three side by side, which the add-on shows in Blender's
Image Editor), and the main report's white-furnace albedo curves.

A curve figure takes the canvas it draws on: core/raster.py's Canvas (a PNG) or core/svg.py's
SvgCanvas (an SVG, the same calls), so the plot's lobe.png and lobe.svg, or a report's figure,
cannot disagree. The heat maps are raster only (their pixels are the data)."""

from __future__ import annotations

import math

import numpy as np

from . import brdf_plot as bp
from .brdf_plot import VIEW_TITLES, luminance, slice_name
from .raster import Canvas, colormap, diverging
from .svg import COLOURS, DASHES, SvgCanvas

SLICE_DECADES = 7  # a log slice shows max / 10^7 .. max
SCALE = 4  # screen pixels per slice pixel
BLACK, GREY, LIGHT = (0.0, 0.0, 0.0), (0.4, 0.4, 0.4), (0.88, 0.88, 0.88)


def _hex(colour: str) -> tuple:
    return tuple(int(colour[i : i + 2], 16) / 255.0 for i in (1, 3, 5))


def number(x: float) -> str:
    if x == 0:
        return "0"
    if abs(x) >= 1e4 or abs(x) < 1e-2:
        return f"{x:.0e}".replace("e+0", "e").replace("e-0", "e-").replace("e+", "e")
    text = f"{x:.3g}"
    return f"{x:.0f}" if "e" in text else text


def slice_figure(values: np.ndarray, title: str, log: bool, diff: bool = False) -> Canvas:
    """A 90 x 90 slice (luminance of RGB values) as a heat map: θh to the right, θd down
    (row 0 at the top, as the slice's rows), with its colour bar. ``log``: log10 over
    SLICE_DECADES decades below the maximum; ``diff``: a relative difference, diverging map
    symmetric about 0."""
    v = luminance(values) if values.ndim == 3 else np.asarray(values, dtype=np.float64)
    size = v.shape[0] * SCALE
    left, top, right, bottom = 58, 34, 110, 48
    c = Canvas(left + size + right, top + size + bottom)
    c.text(left, 20, title, size=13)
    if diff:
        # the scale spans 95% of the pixels, at most +-100%: grazing angles where a G
        # vanishes would otherwise take it all
        span = float(np.nanpercentile(np.abs(v), 95)) if np.isfinite(v).any() else 0.0
        span = min(max(_nice(span), 1e-3), 1.0)
        img, lo, hi = diverging(v / span), -span, span
        ticks = [
            (x, f"{100 * x:+.3g}%" if x else "0") for x in (-span, -span / 2, 0.0, span / 2, span)
        ]
    elif log:
        hi = float(np.max(v)) if np.max(v) > 0 else 1.0
        lo = hi / 10**SLICE_DECADES
        t = (np.log10(np.maximum(v, lo)) - math.log10(lo)) / (math.log10(hi) - math.log10(lo))
        img = colormap(t)
        ticks = [
            (10.0**k, number(10.0**k))
            for k in range(math.ceil(math.log10(lo)), math.floor(math.log10(hi)) + 1)
        ]
    else:
        lo, hi = 0.0, max(1.0, float(np.max(v)))
        img = colormap(v / hi)
        ticks = [(x, number(x)) for x in np.linspace(0, hi, 5)]
    c.paste(left, top, img, scale=SCALE)
    c.rect(left, top, size, size, stroke=GREY)
    for deg in range(0, 91, 15):
        x = left + size * deg / 90.0
        c.line([(x, top + size), (x, top + size + 5)], GREY, width=1)
        c.text(x, top + size + 18, f"{deg}", size=11, anchor="middle")
        y = top + size * deg / 90.0
        c.line([(left - 5, y), (left, y)], GREY, width=1)
        c.text(left - 8, y + 4, f"{deg}", size=11, anchor="end")
    c.text(left + size / 2, top + size + 38, "θh, half-vector angle (°)", size=13, anchor="middle")
    c.text(20, top + size / 2, "θd, difference angle (°)", size=13, anchor="middle", rotate=90)
    # the colour bar
    bx, bw = left + size + 18, 16
    ramp = np.linspace(1, 0, size)[:, None] * np.ones((1, bw))
    bar = diverging(2 * ramp - 1) if diff else colormap(ramp)
    c.paste(bx, top, bar)
    c.rect(bx, top, bw, size, stroke=GREY)
    for value, label in ticks:
        if diff:
            f = (value - lo) / (hi - lo)
        elif log:
            f = (math.log10(value) - math.log10(lo)) / (math.log10(hi) - math.log10(lo))
        else:
            f = (value - lo) / (hi - lo)
        y = top + size * (1 - f)
        c.line([(bx + bw, y), (bx + bw + 4, y)], GREY, width=1)
        c.text(bx + bw + 7, y + 4, label, size=11)
    if log:
        c.text(bx, top + size + 18, f"max {number(hi)}", size=11)
    return c


def _nice(x: float) -> float:
    """The smallest of 1, 2, 5 times a power of ten at or above x."""
    if x <= 0:
        return 0.0
    p = 10 ** math.floor(math.log10(x))
    return next(m * p for m in (1, 2, 5, 10) if m * p >= x)


def lobe_figure(
    lobes: dict, labels: dict, title: str, width: int = 560, height: int = 420, canvas=Canvas
):
    """f_r (n.l) (luminance) in the incidence plane as polar curves: the normal up, θl from
    -90° (left) to 90° (right), one colour per view angle θv, one dash pattern per variant
    (``lobes``: {tag: (len(θv), steps, 3)}); the radius is linear, 1 at the largest value."""
    c = canvas(width, height)
    theta_l = np.radians(bp.lobe_angles())
    peak = max(float(np.max(luminance(v))) for v in lobes.values()) or 1.0
    cx, cy = width / 2, height - 64
    r = min(width / 2 - 40, height - 130)
    for f in (0.25, 0.5, 0.75, 1.0):
        a = np.linspace(-math.pi / 2, math.pi / 2, 91)
        c.line(list(zip(cx + r * f * np.sin(a), cy - r * f * np.cos(a))), LIGHT, width=1)
        c.text(cx + r * f - 3, cy + 14, number(peak * f), size=11, colour=GREY, anchor="end")
    for deg in range(-90, 91, 30):
        a = math.radians(deg)
        c.line([(cx, cy), (cx + r * math.sin(a), cy - r * math.cos(a))], LIGHT, width=1)
        c.text(
            cx + (r + 14) * math.sin(a),
            cy - (r + 14) * math.cos(a) + 4,
            f"{deg}°",
            size=11,
            anchor="middle",
            colour=GREY,
        )
    c.line([(cx - r - 10, cy), (cx + r + 10, cy)], GREY, width=1)
    for i, tv in enumerate(bp.LOBE_VIEW_ANGLES):
        colour = _hex(COLOURS[i % len(COLOURS)])
        a = math.radians(tv)
        c.line(
            [(cx, cy), (cx + 0.18 * r * math.sin(a), cy - 0.18 * r * math.cos(a))], colour, width=3
        )
        for k, values in enumerate(lobes.values()):
            rho = luminance(values[i]) / peak
            dash = DASHES[k % len(DASHES)] or None
            c.line(
                list(zip(cx + r * rho * np.sin(theta_l), cy - r * rho * np.cos(theta_l))),
                colour,
                width=1.8,
                dash=dash,
            )
    c.text(10, 20, title, size=13)
    y = 40
    for i, tv in enumerate(bp.LOBE_VIEW_ANGLES):
        c.line([(10, y - 4), (30, y - 4)], _hex(COLOURS[i % len(COLOURS)]), width=3)
        c.text(36, y, f"θv = {tv:g}°", size=11)
        y += 16
    y = 40
    for k, tag in enumerate(lobes):
        dash = DASHES[k % len(DASHES)] or None
        x0 = width - 12 - max(c.text_width(labels[t], 11) for t in lobes) - 30
        c.line([(x0, y - 4), (x0 + 24, y - 4)], BLACK, width=1.8, dash=dash)
        c.text(x0 + 30, y, labels[tag], size=11)
        y += 16
    c.text(
        cx,
        height - 14,
        f"f_r (n·l), luminance; outer ring {number(peak)}",
        size=11,
        anchor="middle",
        colour=GREY,
    )
    return c


def _view_angle_axes(c, box: tuple, y_max: float, y_label: str):
    """Axes of θv from 0 to 90° (ticks every 15°) against 0 .. y_max (grid lines every 0.25,
    or 0.5 above 2) in the box (left, top, width, height); returns xy(θv, value) -> the
    point on the canvas."""
    left, top, pw, ph = box

    def xy(t, e):
        return left + pw * t / 90.0, top + ph * (1 - e / y_max)

    for e in np.arange(0.0, y_max + 1e-9, 0.25 if y_max <= 2 else 0.5):
        x0, y0 = xy(0, e)
        c.line([(x0, y0), (x0 + pw, y0)], LIGHT, width=1)
        c.text(left - 6, y0 + 4, f"{e:g}", size=11, anchor="end")
    for t in range(0, 91, 15):
        x0, y0 = xy(t, 0)
        c.text(x0, y0 + 16, f"{t}", size=11, anchor="middle")
    c.rect(left, top, pw, ph, stroke=GREY)
    c.text(
        left + pw / 2, top + ph + 34, "θv, view angle from the normal (°)", size=13, anchor="middle"
    )
    c.text(16, top + ph / 2, y_label, size=13, anchor="middle", rotate=90)
    return xy


def albedo_figure(
    albedos: dict, labels: dict, title: str, width: int = 560, height: int = 420, canvas=Canvas
):
    """Directional albedo (luminance) against θv: total solid, specular dashed, diffuse
    dotted; one colour per variant (``albedos``: {tag: {"specular"|"diffuse"|"total":
    (len(θv), 3)}})."""
    c = canvas(width, height)
    tv = bp.albedo_angles()
    top_value = max(1.0, max(float(np.max(luminance(a["total"]))) for a in albedos.values()))
    y_max = math.ceil(top_value * 10 + 0.5) / 10
    left, top = 56, 36
    pw, ph = width - left - 20, height - top - 60 - 16 * (len(albedos) + 1)
    c.text(10, 20, title, size=13)
    xy = _view_angle_axes(c, (left, top, pw, ph), y_max, "directional albedo")
    styles = (("total", None), ("specular", (6.0, 3.0)), ("diffuse", (2.0, 2.0)))
    y = top + ph + 56
    for k, (tag, a) in enumerate(albedos.items()):  # a colour per variant
        colour = COLOURS[k % len(COLOURS)]
        colour = _hex(colour)
        for part, dash in styles:
            c.line([xy(t, e) for t, e in zip(tv, luminance(a[part]))], colour, width=1.8, dash=dash)
        c.line([(left, y - 4), (left + 24, y - 4)], colour, width=2.5)
        c.text(left + 30, y, labels[tag], size=11)
        y += 16
    x = left  # a dash pattern per part
    for part, dash in styles:
        c.line([(x, y - 4), (x + 24, y - 4)], BLACK, width=1.8, dash=dash)
        c.text(x + 30, y, part, size=11)
        x += 30 + c.text_width(part, 11) + 24
    return c


def furnace_figure(curves_by_g: dict, width: int = 720, height: int = 340, canvas=SvgCanvas):
    """The white furnace's directional albedo against θv (core/energy.py): one colour per
    smoothness, one dash pattern per curve set (a G, compensated or not; ``curves_by_g``:
    {label: [{"smoothness", "theta_deg", "albedo"}, ...]}, None where unresolved)."""
    c = canvas(width, height)
    left, top, right = 56, 16, 230
    pw, ph = width - left - right, height - top - 60
    xy = _view_angle_axes(c, (left, top, pw, ph), 1.1, "directional albedo")
    legend_x, y = left + pw + 16, top + 10
    for k, curves in enumerate(curves_by_g.values()):
        dash = DASHES[k % len(DASHES)] or None
        for i, curve in enumerate(curves):
            colour = _hex(COLOURS[i % len(COLOURS)])
            c.line(
                [
                    xy(t, e) if e is not None else (math.nan, math.nan)
                    for t, e in zip(curve["theta_deg"], curve["albedo"])
                ],
                colour,
                width=1.6,
                dash=dash,
            )
            if k == 0:
                c.line([(legend_x, y - 4), (legend_x + 20, y - 4)], colour, width=2.5)
                c.text(legend_x + 26, y, f"smoothness {curve['smoothness']:.1f}", size=11)
                y += 15
    y += 8
    for k, label in enumerate(curves_by_g):
        c.line(
            [(legend_x, y - 4), (legend_x + 20, y - 4)],
            BLACK,
            width=1.2,
            dash=DASHES[k % len(DASHES)] or None,
        )
        c.text(legend_x + 26, y, label, size=11)
        y += 15
    return c


def side_by_side(canvases) -> Canvas:
    """The canvases in one row, top-aligned, on white."""
    canvases = list(canvases)
    out = Canvas(sum(c.width for c in canvases), max(c.height for c in canvases))
    x = 0
    for c in canvases:
        out.paste(x, 0, c.rgb)
        x += c.width
    return out


def figures(settings, results: dict, title: str) -> dict:
    """{file name: Canvas} of every PNG of the plot."""
    labels = results["labels"]
    base = results[""]
    tags = [t for t in results if t not in ("labels", "")]
    out = {}
    name, log = VIEW_TITLES["f_r"]
    out[slice_name() + ".png"] = slice_figure(base["slice"]["f_r"], f"{name}: {title}", log)
    for view in settings.views:
        name, log = VIEW_TITLES[view]
        if view in bp.BRDF_VIEWS and settings.units == "unity":
            name += " x π (Unity's units)"
        out[slice_name(view) + ".png"] = slice_figure(base["slice"][view], name, log)
    for tag in tags:
        values = results[tag]["slice"]["f_r"]
        out[slice_name(tag=tag) + ".png"] = slice_figure(values, f"f_r: {labels[tag]}", True)
        a, b = luminance(base["slice"]["f_r"]), luminance(values)
        with np.errstate(divide="ignore", invalid="ignore"):
            rel = np.where(a > 0, (b - a) / a, np.nan)
        out[slice_name(tag=f"diff_{tag}") + ".png"] = slice_figure(
            rel, f"({labels[tag]} - this) / this", False, diff=True
        )
    out.update({f"{name}.png": c for name, c in curve_figures(results, title).items()})
    out["plot.png"] = side_by_side([out["slice.png"], out["lobe.png"], out["albedo.png"]])
    return out


def curve_figures(results: dict, title: str, canvas=Canvas) -> dict:
    """{"lobe": canvas, "albedo": canvas}: the plot's curves on the given kind of canvas
    (Canvas for its PNGs, SvgCanvas for lobe.svg and albedo.svg)."""
    labels = results["labels"]
    tags = [t for t in results if t != "labels"]
    lobes = {t: results[t]["lobe"] for t in tags}
    albedos = {t: results[t]["albedo"] for t in tags}
    return {
        "lobe": lobe_figure(lobes, labels, "Lobes: " + title, canvas=canvas),
        "albedo": albedo_figure(albedos, labels, "Directional albedo: " + title, canvas=canvas),
    }
