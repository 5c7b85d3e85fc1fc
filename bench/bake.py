"""Bake times: each HDRI's split-sum files baked into an empty cache, and again from the
cache (scripts/bench.py --only bake)."""

import json
import os
import tempfile
import time
from pathlib import Path

BUNDLED = ("city", "courtyard", "forest", "interior", "night", "studio", "sunrise", "sunset")


def synthetic_hdri(path: Path, width: int) -> None:
    """A smooth sky-and-ground gradient with a small sun of radiance 2000."""
    import numpy as np
    from addon.core.hdri import write_float_exr

    h = width // 2
    e = (0.5 - (np.arange(h) + 0.5) / h)[:, None] * np.pi
    s = (np.arange(width) + 0.5)[None, :] / width
    sky = np.where(e > 0, 0.6 + 0.4 * np.sin(e), 0.2 + 0.05 * np.cos(8 * np.pi * s))
    img = np.repeat(sky[:, :, None], 3, axis=2).astype(np.float32) * np.array(
        [0.9, 1.0, 1.1], dtype=np.float32
    )
    r = max(1, width // 512)
    img[h // 4 - r : h // 4 + r, width // 3 - r : width // 3 + r] = 2000.0
    write_float_exr(path, img)


def bench_bake(quick: bool, work: Path) -> dict:
    """Each HDRI baked into an empty cache (the first bake an artist waits for; the DFG tables
    ship with the extension) and again (cached); ``quick`` and ``work`` change nothing."""
    from addon.core import ibl_bake
    from addon.blender.paths import bundled_hdri

    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        inputs = [(name, bundled_hdri(name)) for name in BUNDLED]
        for width in (2048, 4096):
            path = tmp / f"synthetic-{width}.exr"
            synthetic_hdri(path, width)
            inputs.append((f"synthetic {width}x{width // 2}", path))
        for i, (name, path) in enumerate(inputs):
            os.environ["CTLAB_CACHE"] = str(tmp / f"cache-{i}")  # empty
            t = time.perf_counter()
            folder = ibl_bake.bake(path)
            cold = time.perf_counter() - t
            t = time.perf_counter()
            ibl_bake.bake(path)
            cached = time.perf_counter() - t
            info = json.loads((folder / ibl_bake.INFO_FILE).read_text())
            w, h = info["source_size"]
            rows.append(
                {
                    "hdri": name,
                    "size": f"{w}x{h}",
                    "megapixels": round(w * h / 1e6, 3),
                    "bake_seconds": round(cold, 3),
                    "cached_seconds": round(cached, 4),
                    "stages": info["timings"],
                }
            )
            print(rows[-1], flush=True)
    one_k = [r["bake_seconds"] - r["cached_seconds"] for r in rows if r["size"] == "1024x512"]
    return {
        "rows": rows,
        "bundled_1k_first_over_cached_mean_seconds": round(sum(one_k) / len(one_k), 3),
        "bundled_1k_first_over_cached_max_seconds": round(max(one_k), 3),
    }


def bake_table(section: dict) -> list:
    lines = [
        "| HDRI | size | bake (s) | cached (s) | level 1 (s) | level 0 copy (s) |",
        "|---|---|---|---|---|---|",
    ]
    for r in section["rows"]:
        st = r["stages"]
        lines.append(
            f"| {r['hdri']} | {r['size']} | {r['bake_seconds']:.2f} | "
            f"{r['cached_seconds']:.3f} | {st['specular_1.exr']:.2f} | "
            f"{st['specular_0.exr']:.2f} |"
        )
    return lines + [
        "",
        "Bundled 1024x512 HDRIs, a first bake in an empty cache over a cached "
        f"one: mean {section['bundled_1k_first_over_cached_mean_seconds']} s, "
        f"max {section['bundled_1k_first_over_cached_max_seconds']} s.",
    ]
