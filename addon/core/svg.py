"""The reports' SVG figures in one place: the document and the axes of a curve against the
view angle θv (the white furnace's albedo, the BRDF plot's directional albedo)."""

from __future__ import annotations

import numpy as np

# one colour per curve set (Dark2); the dash patterns (on, off) tell a lobe plot's variants
# apart: five are the most a plot has (its model and four --compare variants)
COLOURS = ("#1b9e77", "#d95f02", "#7570b3", "#e7298a", "#66a61e", "#e6ab02", "#a6761d")
DASHES = ((), (7, 3), (2, 2), (12, 3), (1, 4), (4, 6))


def document(width: int, height: int) -> list:
    """The opening of a standalone <svg> on white, as a list of parts ("</svg>" closes it)."""
    return [f"<svg xmlns='http://www.w3.org/2000/svg' width='{width}' height='{height}' "
            f"viewBox='0 0 {width} {height}' font-family='sans-serif' font-size='11'>",
            f"<rect width='{width}' height='{height}' fill='white'/>"]


def view_angle_axes(parts: list, box: tuple, height: int, y_max: float, y_label: str):
    """Axes of θv from 0 to 90° (ticks every 15°) against 0 .. y_max (grid lines every 0.25,
    or 0.5 above 2) in the plot box (left, top, width, height); returns xy(θv, value) -> the
    point in the figure."""
    left, top, pw, ph = box

    def xy(theta, value):
        return left + pw * theta / 90.0, top + ph * (1 - value / y_max)
    parts.append(f"<rect x='{left}' y='{top}' width='{pw}' height='{ph}' fill='none' "
                 "stroke='#888'/>")
    for e in np.arange(0.0, y_max + 1e-9, 0.25 if y_max <= 2 else 0.5):
        x0, y0 = xy(0, e)
        parts.append(f"<line x1='{x0}' y1='{y0:.1f}' x2='{x0 + pw}' y2='{y0:.1f}' "
                     f"stroke='#ddd'/><text x='{left - 6}' y='{y0 + 4:.1f}' "
                     f"text-anchor='end'>{e:g}</text>")
    for t in range(0, 91, 15):
        x0, y0 = xy(t, 0)
        parts.append(f"<text x='{x0:.1f}' y='{y0 + 16}' text-anchor='middle'>{t}</text>")
    parts.append(f"<text x='{left + pw / 2}' y='{height - 4}' text-anchor='middle'>"
                 "&#952;v, the view angle from the normal (degrees)</text>")
    parts.append(f"<text x='12' y='{top + ph / 2}' transform='rotate(-90 12 {top + ph / 2})' "
                 f"text-anchor='middle'>{y_label}</text>")
    return xy


def legend_entry(x: float, y: float, label: str, stroke: str = "#333", dash: str = "",
                 width: float = 2.0) -> str:
    """A legend line (20 units long, at height y - 4) and its label (escaped) after it."""
    import html
    return (f"<line x1='{x}' y1='{y - 4}' x2='{x + 20}' y2='{y - 4}' stroke='{stroke}' "
            f"stroke-width='{width}'{dash}/><text x='{x + 26}' y='{y}'>{html.escape(label)}"
            "</text>")
