"""Write the bitmap font the PNG figures use (addon/data/font_atlas.png and font_atlas.json;
drawn by addon/core/raster.py, which needs neither matplotlib, PIL nor FreeType).

The glyphs are Inter (Copyright (c) 2016 The Inter Project Authors, Rasmus Andersson;
https://rsms.me/inter), licensed under the SIL Open Font License 1.1
(https://openfontlicense.org), rasterised from the copy Blender ships
(datafiles/fonts/Inter.woff2) with Blender's own text drawing (blf.draw_buffer into an image
buffer, which works without a display). Each size keeps, per glyph, its coverage (0..255, a
cell of the atlas), its left bearing, its top above the baseline and its advance width (blf
rounds advances to whole pixels). Characters the font lacks are left out and listed in the
JSON under "missing" (raster.py draws them as '?').

Run it with a bpy Python; the output is the same bytes on every run with the same Blender:

    ./scripts/dev.sh build_font
"""

import json
import os
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

import bpy  # noqa: E402
import blf  # noqa: E402
import imbuf  # noqa: E402
import numpy as np  # noqa: E402

bpy.utils.expose_bundled_modules()

from addon.core.files import DATA_DIR, atomic_path  # noqa: E402
from addon.core.hdri import oiio  # noqa: E402

SIZES = (11, 13, 16, 20)  # pixels per em
CHARS = (
    "".join(map(chr, range(32, 127)))  # printable ASCII, then for the figures:
    + "θφαπ°·×−≤≥Δ²³⁻¹ₕₔ"  # angles, units, 10⁻³, θₕ
    + "βγλμρσω±≈∞–—…→⁰⁴⁵⁶⁷⁸⁹⁺₀₁₂ₒᵢ"
)  # a few more Greek letters, signs, indices
NOT_A_CHAR = "\U0010fffd"  # surely absent: the font's .notdef glyph
ATLAS_WIDTH = 256
SOURCE = (
    "Inter by Rasmus Andersson (Copyright (c) 2016 The Inter Project Authors, "
    "https://rsms.me/inter), SIL Open Font License 1.1 (https://openfontlicense.org); "
    "rasterised from Blender's datafiles/fonts/Inter.woff2 by scripts/build_font.py"
)


def render_cells(fid, size, chars, tmpdir):
    """Coverage (0..255) of each character drawn alone in a 3 em square cell, the pen at
    (size, 2 size) from the cell's top-left: {char: uint8 (3 size, 3 size)}."""
    cell = 3 * size
    ib = imbuf.new((cell * len(chars), cell))
    with blf.bind_imbuf(fid, ib):
        blf.size(fid, size)
        blf.color(fid, 1, 1, 1, 1)
        for i, c in enumerate(chars):
            blf.position(fid, i * cell + size, size, 0)  # y from the bottom
            blf.draw_buffer(fid, c)
    path = os.path.join(tmpdir, f"cells{size}.png")
    imbuf.write(ib, filepath=path)
    OIIO = oiio()
    strip = OIIO.ImageBuf(path).get_pixels(OIIO.UINT8)[:, :, 3]
    return {c: strip[:, i * cell : (i + 1) * cell] for i, c in enumerate(chars)}


def advance(fid, c) -> int:
    """The pen's advance over ``c`` in whole pixels: the ink width of '|' + 8 c + '|' less
    that of '||', over 8 (blf measures ink, not advances)."""
    bars = blf.dimensions(fid, "||")[0]
    return round((blf.dimensions(fid, "|" + c * 8 + "|")[0] - bars) / 8)


def main() -> None:
    if not hasattr(blf, "NO_FALLBACK") or not hasattr(blf, "bind_imbuf"):
        sys.exit(
            f"Blender {bpy.app.version_string}'s blf cannot draw one font alone into an "
            "image; run this with Blender 5.2's bpy (.venv-bpy5.2/bin/python)"
        )
    fid = blf.load(os.path.join(bpy.utils.system_resource("DATAFILES"), "fonts", "Inter.woff2"))
    blf.enable(fid, blf.NO_FALLBACK)  # Inter's glyphs only, no substitutes
    crops, meta, missing = [], {}, set()
    with tempfile.TemporaryDirectory() as tmpdir:
        for size in SIZES:
            cells = render_cells(fid, size, CHARS + NOT_A_CHAR, tmpdir)
            blf.size(fid, size)
            glyphs = {}
            for c in CHARS:
                cov = cells[c]
                if c != " " and np.array_equal(cov, cells[NOT_A_CHAR]):
                    missing.add(c)
                    continue
                rows, cols = np.nonzero(cov)
                if len(rows):
                    r0, r1, c0, c1 = rows.min(), rows.max() + 1, cols.min(), cols.max() + 1
                else:
                    r0 = r1 = 2 * size
                    c0 = c1 = size
                crops.append((size, c, cov[r0:r1, c0:c1]))
                # left bearing, top above the baseline (the pen's row boundary, 2 size)
                glyphs[c] = [int(c0 - size), int(2 * size - r0), advance(fid, c)]
            meta[size] = glyphs

    # Shelf packing in a fixed order, one pixel apart: [x, y, w, h] of each glyph's cell
    x = y = shelf = 0
    for size, c, cov in crops:
        h, w = cov.shape
        if x + w > ATLAS_WIDTH:
            x, y, shelf = 0, y + shelf + 1, 0
        meta[size][c] = [x, y, w, h] + meta[size][c]
        x, shelf = x + w + 1, max(shelf, h)
    atlas = np.zeros((y + shelf, ATLAS_WIDTH), np.uint8)
    for size, c, cov in crops:
        gx, gy = meta[size][c][:2]
        atlas[gy : gy + cov.shape[0], gx : gx + cov.shape[1]] = cov

    sizes = {}
    for size in SIZES:
        g = meta[size]
        sizes[str(size)] = {
            "cap_height": g["H"][5],
            "x_height": g["x"][5],
            "descent": max(g[c][3] - g[c][5] for c in "gjpqy"),
            "glyphs": g,
        }
    write_outputs(
        atlas,
        {
            "source": SOURCE,
            "built_with": f"Blender {bpy.app.version_string}",
            "atlas": "font_atlas.png",
            "glyph": "[x, y, w, h, left, top, advance]: the coverage cell in the atlas (pixels); "
            "its left edge from the pen, its top row above the baseline, the pen's "
            "advance",
            "missing": sorted(missing),
            "sizes": sizes,
        },
    )


def write_outputs(atlas: np.ndarray, data: dict) -> None:
    """font_atlas.png (8-bit grey) and font_atlas.json, each whole or not at all; the JSON
    one glyph a line."""
    OIIO = oiio()
    h, w = atlas.shape
    buf = OIIO.ImageBuf(OIIO.ImageSpec(w, h, 1, OIIO.UINT8))
    buf.set_pixels(OIIO.ROI(0, w, 0, h, 0, 1, 0, 1), atlas[:, :, None])
    png = DATA_DIR / "font_atlas.png"
    with atomic_path(png) as tmp:
        if not buf.write(str(tmp), fileformat="png"):
            raise RuntimeError(f"cannot write {png}: {buf.geterror()}")
    lines = []
    for size, m in data["sizes"].items():
        rows = ",\n".join(
            f"        {json.dumps(c, ensure_ascii=False)}: {json.dumps(v)}"
            for c, v in m["glyphs"].items()
        )
        lines.append(
            f'    "{size}": {{\n'
            f'      "cap_height": {m["cap_height"]}, "x_height": {m["x_height"]}, '
            f'"descent": {m["descent"]},\n'
            f'      "glyphs": {{\n{rows}\n      }}\n    }}'
        )
    head = {k: v for k, v in data.items() if k != "sizes"}
    text = (
        json.dumps(head, indent=2, ensure_ascii=False)[:-2]
        + ',\n  "sizes": {\n'
        + ",\n".join(lines)
        + "\n  }\n}\n"
    )
    assert json.loads(text) == json.loads(json.dumps(data))
    with atomic_path(DATA_DIR / "font_atlas.json") as tmp:
        tmp.write_text(text, encoding="utf-8")
    print(f"wrote {png} ({w}x{h}) and font_atlas.json; missing: {sorted(data['missing'])}")


if __name__ == "__main__":
    main()
