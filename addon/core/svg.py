"""The SVG back end of the figures: a canvas with the raster Canvas's drawing calls (rect,
line, text, text_width; core/raster.py), writing SVG elements instead of pixels. Each figure is
drawn once, by a function of core/figures.py that takes either canvas: a PNG for plot.png and
the add-on's Image Editor, an SVG for the reports and the plot's vector files."""

from __future__ import annotations

import html

import numpy as np

from .raster import text_width

# one colour per curve set (Dark2); the dash patterns (on, off) tell a lobe plot's variants
# apart: five are the most a plot has (its model and four --compare variants)
COLOURS = ("#1b9e77", "#d95f02", "#7570b3", "#e7298a", "#66a61e", "#e6ab02", "#a6761d")
DASHES = ((), (7, 3), (2, 2), (12, 3), (1, 4), (4, 6))


def _colour(c) -> str:
    if isinstance(c, str):
        return c
    r, g, b = (max(0, min(255, round(255 * float(x)))) for x in c[:3])
    return f"#{r:02x}{g:02x}{b:02x}"


class SvgCanvas:
    """A standalone <svg> on white, drawn with the raster Canvas's calls (the same
    coordinates: pixels from the top left)."""

    def __init__(self, width: int, height: int, background=(1.0, 1.0, 1.0)):
        self.width, self.height = int(width), int(height)
        self.parts = [
            f"<svg xmlns='http://www.w3.org/2000/svg' width='{self.width}' "
            f"height='{self.height}' viewBox='0 0 {self.width} {self.height}' "
            "font-family='Inter, sans-serif'>",
            f"<rect width='{self.width}' height='{self.height}' fill='{_colour(background)}'/>",
        ]

    def rect(self, x, y, w, h, fill=None, stroke=None, width=1.0) -> None:
        self.parts.append(
            f"<rect x='{x:.1f}' y='{y:.1f}' width='{w:.1f}' height='{h:.1f}' "
            f"fill='{_colour(fill) if fill is not None else 'none'}'"
            + (
                f" stroke='{_colour(stroke)}' stroke-width='{width:g}'"
                if stroke is not None
                else ""
            )
            + "/>"
        )

    def line(self, points, colour, width=1.5, dash=None) -> None:
        """A polyline; a point with a NaN breaks it there (as the raster canvas's)."""
        pts = np.asarray(points, np.float64).reshape(-1, 2)
        dashes = f" stroke-dasharray='{' '.join(f'{d:g}' for d in dash)}'" if dash else ""
        for run in np.split(pts, np.flatnonzero(~np.isfinite(pts).all(axis=1))):
            run = run[np.isfinite(run).all(axis=1)]
            if len(run) < 2:
                continue
            coords = " ".join(f"{x:.1f},{y:.1f}" for x, y in run)
            self.parts.append(
                f"<polyline points='{coords}' fill='none' "
                f"stroke='{_colour(colour)}' stroke-width='{width:g}' "
                f"stroke-linejoin='round' stroke-linecap='round'{dashes}/>"
            )

    def text_width(self, s: str, size=13) -> float:
        return text_width(s, size)

    def text(self, x, y, s, colour=(0, 0, 0), size=13, anchor="start", rotate=0) -> None:
        turn = f" transform='rotate(-90 {x:.1f} {y:.1f})'" if rotate == 90 else ""
        self.parts.append(
            f"<text x='{x:.1f}' y='{y:.1f}' font-size='{size}' "
            f"text-anchor='{anchor}' fill='{_colour(colour)}'{turn}>"
            f"{html.escape(str(s))}</text>"
        )

    def svg(self) -> str:
        return "".join(self.parts) + "</svg>"
