"""The raster canvas of the PNG figures (addon/core/raster.py): text where it should be, lines
with the ink they should hold, the colour maps, and PNGs written whole."""

import json
import math

import numpy as np
import pytest

from addon.core import compare, raster
from addon.core.errors import UserError
from addon.core.files import DATA_DIR
from addon.core.hdri import oiio
from addon.core.raster import Canvas, colormap, diverging


def ink(c: Canvas) -> np.ndarray:
    """How much black there is in each pixel of a white canvas (0..1)."""
    return 1.0 - c.rgb.mean(axis=2)


def bbox(a: np.ndarray, threshold=0.02):
    """(x0, y0, x1, y1) of the pixels above ``threshold``, x1 and y1 exclusive."""
    rows, cols = np.nonzero(a > threshold)
    return cols.min(), rows.min(), cols.max() + 1, rows.max() + 1


def luminance(rgb: np.ndarray) -> np.ndarray:
    lin = np.where(rgb <= 0.04045, rgb / 12.92, ((rgb + 0.055) / 1.055) ** 2.4)
    return lin @ np.array([0.2126, 0.7152, 0.0722])


# --- The font ------------------------------------------------------------------------


def test_the_atlas_names_its_source_and_holds_every_glyph():
    meta = json.loads((DATA_DIR / "font_atlas.json").read_text(encoding="utf-8"))
    assert "Inter" in meta["source"] and "Open Font License 1.1" in meta["source"]
    atlas, _ = raster._glyphs(13)
    for size in raster.font_sizes():
        _, table = raster._glyphs(size)
        assert set(map(chr, range(32, 127))) <= set(table)
        assert set("θφαπ°·×−≤≥Δ²³⁻¹") <= set(table)
        for x, y, w, h, *_ in table.values():
            assert 0 <= x and x + w <= atlas.shape[1] and 0 <= y and y + h <= atlas.shape[0]
    total = sum(p.stat().st_size for p in DATA_DIR.glob("font_atlas.*"))
    assert total < 200_000


# --- Text ----------------------------------------------------------------------------


def test_text_sits_on_its_baseline_inside_its_box():
    for size in raster.font_sizes():
        c = Canvas(300, 80)
        c.text(20, 50, "H", size=size)
        x0, y0, x1, y1 = bbox(ink(c))
        assert y1 == 50, "a capital's ink ends on the row above the baseline"
        assert 0.65 * size <= 50 - y0 <= 0.8 * size, "cap height ~0.73 em"
        assert 19 <= x0 <= 22 and x1 <= 20 + c.text_width("H", size) + 1

        c = Canvas(300, 80)
        c.text(20, 50, "Hxgjpy|", size=size)
        a = ink(c)
        x0, y0, x1, y1 = bbox(a)
        width = c.text_width("Hxgjpy|", size)
        assert 18 <= x0 and x1 <= 20 + width + 2
        assert 50 - 1.1 * size <= y0 and y1 <= 50 + 0.35 * size
        assert y1 > 50, "descenders go below the baseline"
        outside = a.copy()
        outside[int(50 - 1.1 * size) : int(50 + 0.35 * size) + 1, 18 : int(20 + width + 3)] = 0
        assert outside.max() == 0
        assert a.sum() > 0.5 * size * len("Hxgjpy|")


def test_text_width_grows_and_anchors_align():
    c = Canvas(300, 60)
    widths = [c.text_width("m" * n, 13) for n in range(1, 6)]
    assert all(b > a for a, b in zip(widths, widths[1:]))
    assert widths[4] == pytest.approx(5 * widths[0])
    assert c.text_width("mm", 20) > c.text_width("mm", 11)

    c.text(250, 40, "end here", size=13, anchor="end")
    x0, _, x1, _ = bbox(ink(c))
    assert abs(x1 - 250) <= 1 and x0 == pytest.approx(250 - c.text_width("end here"), abs=2)

    c = Canvas(300, 60)
    c.text(150, 40, "centred", size=13, anchor="middle")
    x0, _, x1, _ = bbox(ink(c))
    assert abs((x0 + x1) / 2 - 150) <= 1.5


def test_rotated_text_reads_upwards_with_the_extents_swapped():
    flat = Canvas(200, 200)
    flat.text(50, 100, "Albedo (gy)", size=16)
    up = Canvas(200, 200)
    up.text(100, 150, "Albedo (gy)", size=16, rotate=90)
    fx0, fy0, fx1, fy1 = bbox(ink(flat))
    ux0, uy0, ux1, uy1 = bbox(ink(up))
    assert (ux1 - ux0, uy1 - uy0) == (fy1 - fy0, fx1 - fx0)
    assert ux0 < 100 - 10 and ux1 <= 100 + 0.35 * 16, "ascenders to the left of the baseline"
    assert uy1 <= 151 and uy0 == pytest.approx(150 - up.text_width("Albedo (gy)", 16), abs=2)
    # the same pixels turned a quarter counter-clockwise: the 'A' at the bottom
    assert np.array_equal(ink(up)[uy0:uy1, ux0:ux1], np.rot90(ink(flat)[fy0:fy1, fx0:fx1]))


def test_missing_glyphs_draw_as_a_question_mark():
    a, b = Canvas(100, 40), Canvas(100, 40)
    a.text(10, 30, "x中y\x00")
    b.text(10, 30, "x?y?")
    assert np.array_equal(a.rgb, b.rgb) and ink(a).sum() > 0


def test_text_off_the_canvas_is_clipped():
    c = Canvas(40, 20)
    c.text(-30, 5, "clipped on every side", size=20)
    c.text(30, 30, "gy", size=20, rotate=90)
    assert c.rgb.shape == (20, 40, 3)


# --- Lines ---------------------------------------------------------------------------


@pytest.mark.parametrize(
    "p, q, width",
    [
        ((20, 30.5), (180, 30.5), 2.0),
        ((20, 20), (150, 120), 1.5),
        ((15, 140), (170, 60), 3.0),
        ((20, 20), (170, 150), 0.5),
    ],
)
def test_a_line_holds_length_times_width_of_ink(p, q, width):
    c = Canvas(200, 160)
    c.line([p, q], (0, 0, 0), width=width)
    length = math.dist(p, q)
    assert ink(c).sum() == pytest.approx(length * width, rel=0.1)


def test_a_line_is_symmetric_about_itself():
    c = Canvas(100, 100)
    c.line([(10, 10), (90, 90)], (0, 0, 0), width=2.0)
    a = ink(c)
    assert np.allclose(a, a.T, atol=1e-5) and a.max() == pytest.approx(1.0, abs=1e-5)

    c = Canvas(100, 100)
    c.line([(10, 50), (90, 50)], (0, 0, 0), width=3.0)  # centred on a row boundary
    column = ink(c)[:, 50]
    assert np.allclose(column[:50], column[50:][::-1], atol=1e-6)
    assert column[48:52].tolist() == pytest.approx([0.5, 1, 1, 0.5])


def test_a_curve_is_anti_aliased_without_gaps():
    c = Canvas(200, 200)
    t = np.linspace(0, 2 * np.pi, 400)
    c.line(np.stack([100 + 80 * np.cos(t), 100 + 80 * np.sin(t)], 1), (0, 0, 0), width=1.5)
    a = ink(c)
    assert a.sum() == pytest.approx(2 * np.pi * 80 * 1.5, rel=0.1)
    assert 0 < (a[(a > 0.02) & (a < 0.98)]).size, "partial coverage at the edges"
    ring = [
        a[
            int(100 + 80 * np.sin(s)) - 2 : int(100 + 80 * np.sin(s)) + 3,
            int(100 + 80 * np.cos(s)) - 2 : int(100 + 80 * np.cos(s)) + 3,
        ].sum()
        for s in np.linspace(0, 2 * np.pi, 90)
    ]
    assert min(ring) > 2.0


def test_dashes_leave_gaps():
    c = Canvas(200, 40)
    c.line([(10, 20.5), (190, 20.5)], (0, 0, 0), width=1.5, dash=(6, 4))
    columns = ink(c).sum(axis=0)[10:190]
    inked = columns > 0.05
    runs = np.flatnonzero(np.diff(inked.astype(int)) == 1)
    assert len(runs) >= 16, "18 dashes of 6 px in 180 px"
    assert 0.5 < inked.mean() < 0.75
    assert ink(c).sum() == pytest.approx(18 * 6 * 1.5, rel=0.15)


def test_lines_are_clipped_at_the_edges():
    c = Canvas(100, 40)
    c.line([(-50, 10.5), (250, 10.5)], (0, 0, 0), width=2.0)
    c.line([(-50, -20), (-10, -5)], (0, 0, 0), width=2.0)  # wholly outside
    c.line([(np.nan, 5), (np.nan, np.nan)], (0, 0, 0))
    assert ink(c).sum() == pytest.approx(100 * 2.0, rel=1e-4)


def test_nan_points_break_the_line():
    c = Canvas(120, 40)
    c.line([(10, 20.5), (50, 20.5), (np.nan, np.nan), (60, 20.5), (100, 20.5)], (0, 0, 0))
    a = ink(c)
    assert a[:, 30].sum() > 1 and a[:, 80].sum() > 1 and a[:, 55].sum() == 0


def test_colour_is_blended_by_coverage():
    c = Canvas(60, 20, background=(0.0, 0.0, 1.0))
    c.line([(10, 10), (50, 10)], (1.0, 0.0, 0.0), width=2.0)
    px = c.rgb[9, 30]
    assert px.tolist() == pytest.approx([1, 0, 0])
    px = c.rgb[:, 30]
    assert np.allclose(px[:, 0] + px[:, 2], 1.0)  # red over blue, nothing else


# --- Images and rectangles -----------------------------------------------------------


def test_paste_scales_by_whole_pixels_and_clips():
    img = np.array([[[1, 0, 0], [0, 1, 0]], [[0, 0, 1], [1, 1, 0]]], np.float32)
    c = Canvas(20, 20, background=(0, 0, 0))
    c.paste(3, 4, img, scale=3)
    assert np.array_equal(c.rgb[4:10, 3:9], np.repeat(np.repeat(img, 3, 0), 3, 1))
    assert c.rgb[:4].max() == 0 and c.rgb[10:].max() == 0 and c.rgb[:, 9:].max() == 0
    c = Canvas(5, 5, background=(0, 0, 0))
    c.paste(-2, 3, img, scale=2)  # partly off the left and bottom
    assert c.rgb[3, 0].tolist() == [0, 1, 0] and c.rgb[3, 2].max() == 0
    assert c.rgb[4, 0].tolist() == [0, 1, 0]


def test_rect_fills_and_strokes_whole_pixels():
    c = Canvas(30, 30)
    c.rect(5, 6, 10, 8, fill=(0, 0, 0))
    assert bbox(ink(c)) == (5, 6, 15, 14) and ink(c).sum() == 80
    c = Canvas(30, 30)
    c.rect(5, 6, 10, 8, stroke=(0, 0, 0), width=1)
    assert bbox(ink(c)) == (5, 6, 15, 14) and ink(c).sum() == 2 * 10 + 2 * 6
    assert ink(c)[7:13, 6:14].max() == 0


# --- Colour maps ---------------------------------------------------------------------


def test_colormap_is_viridis():
    assert colormap(0.0).tolist() == pytest.approx([0.267, 0.005, 0.329], abs=0.02)
    assert colormap(1.0).tolist() == pytest.approx([0.993, 0.906, 0.144], abs=0.02)
    assert colormap(0.5).tolist() == pytest.approx([0.128, 0.567, 0.551], abs=0.01)
    assert colormap(0.25).tolist() == pytest.approx([0.230, 0.322, 0.546], abs=0.01)
    y = luminance(colormap(np.linspace(0, 1, 1001)))
    assert np.all(np.diff(y) > 0)
    assert colormap(np.array([-1.0, 2.0])).tolist() == [
        colormap(0.0).tolist(),
        colormap(1.0).tolist(),
    ]
    assert colormap(np.full((4, 5), np.nan)).shape == (4, 5, 3)
    assert colormap(np.nan).tolist() == pytest.approx([0.5, 0.5, 0.5])


def test_diverging_is_blue_white_red_and_symmetric():
    assert min(diverging(0.0)) > 0.95
    blue, red = diverging(-1.0), diverging(1.0)
    assert blue[2] > 2 * blue[0] and red[0] > 2 * red[2]
    t = np.linspace(0, 1, 201)
    y_pos, y_neg = luminance(diverging(t)), luminance(diverging(-t))
    assert np.abs(y_pos - y_neg).max() < 0.05
    assert np.all(np.diff(y_pos) < 0) and np.all(np.diff(y_neg) < 0)
    assert diverging(np.nan).tolist() == pytest.approx([0.5, 0.5, 0.5])
    assert diverging(3.0).tolist() == red.tolist()


# --- PNG -----------------------------------------------------------------------------


def test_save_png_round_trips_and_leaves_no_temporary(tmp_path):
    c = Canvas(37, 23, background=(0.2, 0.4, 0.6))
    c.paste(0, 0, colormap(np.linspace(0, 1, 37))[None].repeat(5, 0))
    c.rgb[10, 10] = (1.5, -0.5, 0.5)  # out of range: clipped
    c.save_png(tmp_path / "plot.png")
    assert [p.name for p in tmp_path.iterdir()] == ["plot.png"]
    OIIO = oiio()
    buf = OIIO.ImageBuf(str(tmp_path / "plot.png"))
    spec = buf.spec()
    assert (spec.width, spec.height, spec.nchannels) == (37, 23, 3)
    assert spec.format == OIIO.UINT8
    back = buf.get_pixels(OIIO.FLOAT)
    assert np.abs(back - np.clip(c.rgb, 0, 1)).max() <= 0.5 / 255 + 1e-6


def test_a_failed_save_leaves_nothing(tmp_path, monkeypatch):
    c = Canvas(10, 10)
    with pytest.raises(UserError):
        c.save_png(tmp_path / "missing" / "plot.png")
    assert list(tmp_path.iterdir()) == []

    (tmp_path / "plot.png").write_bytes(b"old")
    (tmp_path / "old.png").hardlink_to(tmp_path / "plot.png")
    c.save_png(tmp_path / "plot.png")  # replaced by a rename, not rewritten
    assert (tmp_path / "plot.png").read_bytes()[:4] == b"\x89PNG"
    assert (tmp_path / "old.png").read_bytes() == b"old"
    (tmp_path / "old.png").unlink()

    class HalfWritten:  # a writer that fails halfway
        def __init__(self, spec):
            pass

        def set_pixels(self, roi, pixels):
            return True

        def write(self, path, fileformat=""):
            open(path, "wb").write(b"\x89PNG half")
            return False

        def geterror(self):
            return "No space left on device"

    class FailingOIIO:
        def __getattr__(self, name):
            return HalfWritten if name == "ImageBuf" else getattr(oiio(), name)

    good = (tmp_path / "plot.png").read_bytes()
    monkeypatch.setattr(compare, "oiio", FailingOIIO)  # the one PNG writer
    with pytest.raises(UserError, match="No space left"):
        c.save_png(tmp_path / "plot.png")
    assert (tmp_path / "plot.png").read_bytes() == good
    assert [p.name for p in tmp_path.iterdir()] == ["plot.png"]
