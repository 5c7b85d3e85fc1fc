"""A small raster canvas for PNG figures (BRDF slices, lobe curves, albedo curves) without
matplotlib, PIL or FreeType: filled and stroked rectangles, anti-aliased polylines, text from
the bitmap font the extension ships (addon/data/font_atlas.*, Inter, written by
scripts/build_font.py) and two colour maps. Pixels are display-referred sRGB in 0..1, the
origin at the top-left; pixel (col, row) covers [col, col + 1) x [row, row + 1), so a 1 px
line at y = row + 0.5 fills exactly one row. Coverage is blended linearly in display values."""

from __future__ import annotations

import functools
import json

import numpy as np

from .errors import UserError
from .files import DATA_DIR
from .hdri import oiio


# --- The font ------------------------------------------------------------------------


@functools.cache
def _font() -> dict:
    """{size: (coverage atlas float32 0..1, {char: (x, y, w, h, left, top, advance)})}."""
    meta = json.loads((DATA_DIR / "font_atlas.json").read_text(encoding="utf-8"))
    OIIO = oiio()
    path = DATA_DIR / meta["atlas"]
    inp = OIIO.ImageInput.open(str(path))
    if inp is None:
        raise UserError(f"the font atlas is unreadable: {path}; reinstall the extension")
    try:
        spec = inp.spec()
        pixels = inp.read_image(0, 0, 0, 1, OIIO.UINT8)
    finally:
        inp.close()
    atlas = np.asarray(pixels, np.float32).reshape(spec.height, spec.width) / 255.0
    return {
        int(s): (atlas, {c: tuple(g) for c, g in m["glyphs"].items()})
        for s, m in meta["sizes"].items()
    }


def font_sizes() -> tuple:
    """The pixel sizes the font was rasterised at; text at any other size uses the nearest."""
    return tuple(sorted(_font()))


def _glyphs(size: float):
    """The atlas and glyph table of the size nearest to ``size`` (the larger on a tie)."""
    font = _font()
    return font[min(font, key=lambda s: (abs(s - size), -s))]


def _glyph(table: dict, c: str) -> tuple:
    return table.get(c) or table.get(" " if c in "\t\n" else "?")


# --- Colour maps ---------------------------------------------------------------------

# viridis (van der Walt and Smith, CC0; matplotlib's 256-entry table) at t = 0, 1/32, ..., 1;
# linear interpolation between these stays within 0.007 of the table.
_VIRIDIS = np.array(
    [
        (0.267, 0.005, 0.329),
        (0.277, 0.050, 0.376),
        (0.282, 0.095, 0.417),
        (0.283, 0.135, 0.453),
        (0.279, 0.175, 0.483),
        (0.271, 0.213, 0.507),
        (0.259, 0.251, 0.524),
        (0.245, 0.287, 0.537),
        (0.230, 0.321, 0.545),
        (0.215, 0.354, 0.551),
        (0.200, 0.386, 0.555),
        (0.186, 0.417, 0.557),
        (0.173, 0.447, 0.558),
        (0.161, 0.477, 0.558),
        (0.150, 0.506, 0.557),
        (0.138, 0.536, 0.555),
        (0.128, 0.565, 0.551),
        (0.121, 0.594, 0.544),
        (0.120, 0.624, 0.534),
        (0.131, 0.653, 0.521),
        (0.155, 0.682, 0.503),
        (0.193, 0.710, 0.481),
        (0.241, 0.737, 0.455),
        (0.299, 0.762, 0.423),
        (0.363, 0.787, 0.387),
        (0.433, 0.809, 0.345),
        (0.508, 0.829, 0.299),
        (0.587, 0.847, 0.249),
        (0.669, 0.862, 0.195),
        (0.753, 0.875, 0.143),
        (0.836, 0.886, 0.102),
        (0.917, 0.896, 0.101),
        (0.993, 0.906, 0.144),
    ]
)

# ColorBrewer RdBu (11 classes, Cynthia Brewer, Apache-2.0), from blue at -1 to red at +1
_RDBU = np.array(
    [
        [int(h[i : i + 2], 16) / 255.0 for i in (0, 2, 4)]
        for h in (
            "053061",
            "2166ac",
            "4393c3",
            "92c5de",
            "d1e5f0",
            "f7f7f7",
            "fddbc7",
            "f4a582",
            "d6604d",
            "b2182b",
            "67001f",
        )
    ]
)

NAN_GREY = (0.5, 0.5, 0.5)


def _interpolate(table: np.ndarray, t, lo: float, hi: float) -> np.ndarray:
    """Piecewise-linear lookup of ``t`` (clipped to [lo, hi], evenly spaced over the table;
    NaN gives NAN_GREY): float32 (..., 3)."""
    t = np.asarray(t, dtype=np.float64)
    u = (np.clip(t, lo, hi) - lo) / (hi - lo) * (len(table) - 1)
    i = np.clip(np.floor(np.nan_to_num(u)).astype(int), 0, len(table) - 2)
    f = (np.nan_to_num(u) - i)[..., None]
    out = table[i] * (1 - f) + table[i + 1] * f
    out[np.isnan(t)] = NAN_GREY
    return out.astype(np.float32)


def colormap(t) -> np.ndarray:
    """viridis, a perceptually uniform sequential map: t in [0, 1] (clipped; NaN is grey) to
    display sRGB, shape t.shape + (3,)."""
    return _interpolate(_VIRIDIS, t, 0.0, 1.0)


def diverging(t) -> np.ndarray:
    """Blue - white - red (ColorBrewer RdBu, interpolated): t in [-1, 1] (clipped; NaN is
    grey) to display sRGB, shape t.shape + (3,); 0 is a near-white (0.97) grey."""
    return _interpolate(_RDBU, t, -1.0, 1.0)


# --- The canvas ----------------------------------------------------------------------


def text_width(s: str, size=13) -> float:
    """The pen's advance over ``s`` in px at the font's nearest size (the ink may overhang by
    a pixel)."""
    _, table = _glyphs(size)
    return float(sum(_glyph(table, c)[6] for c in str(s)))


class Canvas:
    """An RGB image to draw on: ``rgb`` float32 (height, width, 3), display sRGB in 0..1."""

    def __init__(self, width: int, height: int, background=(1.0, 1.0, 1.0)):
        self.width, self.height = int(width), int(height)
        self.rgb = np.empty((self.height, self.width, 3), np.float32)
        self.rgb[:] = np.asarray(background, np.float32)

    # Compositing

    def _blend(self, x: int, y: int, coverage: np.ndarray, colour) -> None:
        """Blend ``colour`` over the canvas with ``coverage`` (h, w, 0..1) placed at (x, y),
        clipped at the edges."""
        h, w = coverage.shape
        x0, y0 = max(x, 0), max(y, 0)
        x1, y1 = min(x + w, self.width), min(y + h, self.height)
        if x0 >= x1 or y0 >= y1:
            return
        a = coverage[y0 - y : y1 - y, x0 - x : x1 - x, None]
        region = self.rgb[y0:y1, x0:x1]
        region += (np.asarray(colour, np.float32) - region) * a

    def paste(self, x: int, y: int, rgb: np.ndarray, scale: int = 1) -> None:
        """Copy an image (h, w, 3), or grey (h, w), to top-left (x, y), each pixel a
        scale x scale block (nearest neighbour), clipped at the edges."""
        img = np.asarray(rgb, np.float32)
        if img.ndim == 2:
            img = np.repeat(img[:, :, None], 3, axis=2)
        if scale != 1:
            img = np.repeat(np.repeat(img, int(scale), axis=0), int(scale), axis=1)
        h, w = img.shape[:2]
        x, y = int(x), int(y)
        x0, y0 = max(x, 0), max(y, 0)
        x1, y1 = min(x + w, self.width), min(y + h, self.height)
        if x0 < x1 and y0 < y1:
            self.rgb[y0:y1, x0:x1] = img[y0 - y : y1 - y, x0 - x : x1 - x, :3]

    def rect(self, x, y, w, h, fill=None, stroke=None, width=1.0) -> None:
        """Fill the pixels [x, x + w) x [y, y + h) (rounded to whole pixels) with ``fill`` and
        draw ``stroke`` as a crisp border round(width) px wide inside that edge."""
        x0, y0 = round(x), round(y)
        x1, y1 = round(x + w), round(y + h)
        if x1 <= x0 or y1 <= y0:
            return
        if fill is not None:
            self._blend(x0, y0, np.ones((y1 - y0, x1 - x0), np.float32), fill)
        if stroke is not None:
            b = max(1, round(width))
            mask = np.ones((y1 - y0, x1 - x0), np.float32)
            mask[b:-b, b:-b] = 0.0
            self._blend(x0, y0, mask, stroke)

    def line(self, points, colour, width=1.5, dash=None) -> None:
        """An anti-aliased polyline through [(x, y), ...] (pixel coordinates, floats) with
        round joins and caps; ``dash`` = (on, off) in px gives dashes ``on`` long (caps
        included). A point with a NaN breaks the line there."""
        pts = np.asarray(points, np.float64).reshape(-1, 2)
        finite = pts[np.isfinite(pts).all(axis=1)]
        if not len(finite):
            return
        reach = max(width, 1.0) / 2 + 2  # coverage only near the points
        x0, y0 = np.maximum(np.floor(finite.min(axis=0) - reach), 0).astype(int)
        x1, y1 = np.minimum(np.ceil(finite.max(axis=0) + reach), (self.width, self.height)).astype(
            int
        )
        if x0 >= x1 or y0 >= y1:
            return
        coverage = np.zeros((y1 - y0, x1 - x0), np.float32)
        pts = pts - (x0, y0)
        for run in np.split(pts, np.flatnonzero(~np.isfinite(pts).all(axis=1))):
            run = run[np.isfinite(run).all(axis=1)]
            if not len(run):
                continue
            for piece in _dashes(run, dash, width) if dash else [run]:
                _stroke(coverage, piece, width)
        self._blend(x0, y0, coverage, colour)

    # Text

    def text_width(self, s: str, size=13) -> float:
        return text_width(s, size)

    def text(self, x, y, s, colour=(0, 0, 0), size=13, anchor="start", rotate=0) -> None:
        """Draw ``s`` with its baseline through (x, y): starting there (anchor 'start'),
        centred on it ('middle') or ending there ('end'). ``rotate`` 90 turns it
        counter-clockwise (reading upwards, for a y-axis label), about (x, y). One line; the
        font's nearest size is used (font_sizes); characters it lacks are drawn as '?'."""
        if rotate not in (0, 90):
            raise ValueError(f"rotate must be 0 or 90, not {rotate!r}")
        if anchor not in ("start", "middle", "end"):
            raise ValueError(f"anchor must be start, middle or end, not {anchor!r}")
        s = str(s)
        atlas, table = _glyphs(size)
        shift = {"start": 0.0, "middle": -0.5, "end": -1.0}[anchor] * self.text_width(s, size)
        pen, cells = round(shift), []  # relative to the anchor
        for c in s:
            gx, gy, w, h, left, top, adv = _glyph(table, c)
            if w and h:
                cells.append((pen + left, -top, atlas[gy : gy + h, gx : gx + w]))
            pen += adv
        if not cells:
            return
        x0 = min(cx for cx, _, g in cells)
        y0 = min(cy for _, cy, g in cells)
        x1 = max(cx + g.shape[1] for cx, _, g in cells)
        y1 = max(cy + g.shape[0] for _, cy, g in cells)
        mask = np.zeros((y1 - y0, x1 - x0), np.float32)
        for cx, cy, g in cells:
            sub = mask[cy - y0 : cy - y0 + g.shape[0], cx - x0 : cx - x0 + g.shape[1]]
            np.maximum(sub, g, out=sub)
        ax, ay = -x0, -y0  # the anchor in the mask
        if rotate == 0:
            self._blend(round(x) - ax, round(y) - ay, mask, colour)
        else:  # (dx, dy) -> (dy, -dx): the mask's anchor moves to (ay, width - ax)
            self._blend(round(x) - ay, round(y) - (mask.shape[1] - ax), np.rot90(mask), colour)

    # Output

    def save_png(self, path) -> None:
        """An 8-bit RGB PNG of the canvas, written whole or not at all (the one PNG writer,
        compare.write_png)."""
        from .compare import write_png

        write_png(path, self.rgb)


# --- Lines ---------------------------------------------------------------------------


def _stroke(coverage: np.ndarray, pts: np.ndarray, width: float) -> None:
    """Raise ``coverage`` to that of a polyline ``width`` px wide: per segment, 1 within
    width/2 of it, falling to 0 over one pixel (so each cross-section holds ``width`` of ink;
    thinner lines are one pixel wide and fainter)."""
    r = max(width, 1.0) / 2
    fade = min(width, 1.0)
    height, w = coverage.shape
    segments = zip(pts[:-1], pts[1:]) if len(pts) > 1 else [(pts[0], pts[0])]
    for p, q in segments:
        x0 = max(int(np.floor(min(p[0], q[0]) - r - 1)), 0)
        x1 = min(int(np.ceil(max(p[0], q[0]) + r + 1)), w)
        y0 = max(int(np.floor(min(p[1], q[1]) - r - 1)), 0)
        y1 = min(int(np.ceil(max(p[1], q[1]) + r + 1)), height)
        if x0 >= x1 or y0 >= y1:
            continue
        px = np.arange(x0, x1) + 0.5 - p[0]
        py = (np.arange(y0, y1) + 0.5 - p[1])[:, None]
        d = q - p
        length2 = float(d @ d)
        t = np.clip((px * d[0] + py * d[1]) / length2, 0, 1) if length2 > 0 else 0.0
        dist = np.hypot(px - t * d[0], py - t * d[1])
        c = np.clip(r + 0.5 - dist, 0, 1) * fade
        sub = coverage[y0:y1, x0:x1]
        np.maximum(sub, c.astype(np.float32), out=sub)


def _dashes(pts: np.ndarray, dash, width: float) -> list:
    """The pieces of a polyline that a dash pattern (on, off) draws, each shortened by the
    round caps so that a dash's ink is ``on`` long."""
    on, off = float(dash[0]), float(dash[1])
    s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(pts, axis=0).T))])
    cap = max(width, 1.0) / 2
    pieces = []
    for start in np.arange(0.0, s[-1], max(on + off, 1e-3)):
        a, b = start + cap, min(start + on, s[-1]) - cap
        if b < a:
            a = b = (start + min(start + on, s[-1])) / 2
        inner = (s > a) & (s < b)
        along = np.concatenate([[a], s[inner], [b]])
        pieces.append(
            np.stack([np.interp(along, s, pts[:, 0]), np.interp(along, s, pts[:, 1])], axis=1)
        )
    return pieces
