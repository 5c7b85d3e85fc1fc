"""Benchmarks: render times (the OSL Cook-Torrance matrix, in each IBL mode, against Principled
BSDF at equal samples) and bake times (the split-sum files of an HDRI).

Writes bench/results.json and bench/results.md (the README's tables). Each figure is from one
run on this machine; Cycles' synchronisation (scene + shader compile) is reported apart from
its render time.

    .venv-bpy<series>/bin/python scripts/bench.py [--quick] [--only render|bake]

``--only`` re-runs one section and keeps the other from the existing results.json.
"""

import argparse
import json
import os
import platform
import shutil
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
import bpy  # noqa: E402,F401  (Blender as a module)

from addon.core.model import ModelOptions  # noqa: E402
from addon.core.settings import MatrixSettings  # noqa: E402
from addon.jobs import pipeline  # noqa: E402

OUT = ROOT / "bench"
BUNDLED = ("city", "courtyard", "forest", "interior", "night", "studio", "sunrise", "sunset")


# --- Render times ------------------------------------------------------------------------

def one_render(shader, ibl, grid, size, samples, work, engine="cycles"):
    s = MatrixSettings(rows=grid, cols=grid, width=size, height=size, shader=shader,
                       model=ModelOptions(view="full", ibl=ibl))
    start = time.perf_counter()
    d = pipeline.render_one(s, work / f"{shader}-{ibl}-{grid}-{size}-{samples}-{engine}",
                            samples, engine=engine)
    name = shader if shader == "principled" else f"{shader} {ibl}" + (
        " (eevee)" if engine == "eevee" else "")
    return {"shader": name, "grid": f"{grid}x{grid}", "size": size, "samples": samples,
            "env_samples": s.model.env_samples, "wall_seconds": round(time.perf_counter() - start, 2),
            "sync_seconds": d.get("sync_seconds"),
            # EEVEE writes no timing metadata: its figure is the wall time of the render call
            "render_seconds": d.get("cycles_render_seconds", d["render_seconds"])}


def bench_render(quick: bool) -> dict:
    main_cfg = (7, 256, 16) if quick else (7, 512, 64)
    sizes = (128, 256) if quick else (128, 256, 512)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        for shader, ibl, engine in (("osl", "reference", "cycles"), ("principled", "reference", "cycles"),
                                    ("osl", "split_sum", "cycles"), ("osl", "unity", "cycles"),
                                    ("nodes", "split_sum", "cycles"), ("nodes", "split_sum", "eevee")):
            rows.append(dict(one_render(shader, ibl, *main_cfg, work, engine), case="default matrix"))
            print(rows[-1], flush=True)
        for g in (3, 7, 11):
            for shader in ("osl", "principled"):
                rows.append(dict(one_render(shader, "reference", g, 256, 16, work), case="grid"))
                print(rows[-1], flush=True)
        for size in sizes:
            for shader in ("osl", "principled"):
                rows.append(dict(one_render(shader, "reference", 7, size, 16, work),
                                 case="resolution"))
                print(rows[-1], flush=True)
    by = {r["shader"]: r for r in rows if r["case"] == "default matrix"}
    ref = by["principled"]
    return {"rows": rows, "ratios_over_principled_render": {
        k: round(r["render_seconds"] / ref["render_seconds"], 2) for k, r in by.items()},
        "ratio_osl_over_principled_wall": round(by["osl reference"]["wall_seconds"]
                                                / ref["wall_seconds"], 2)}


def render_table(section: dict) -> list:
    lines = ["| case | shader | grid | size | samples | sync (s) | render (s) | wall (s) |",
             "|---|---|---|---|---|---|---|---|"]
    for r in section["rows"]:
        sync = "–" if r["sync_seconds"] is None else f"{r['sync_seconds']:.2f}"
        lines.append(f"| {r['case']} | {r['shader']} | {r['grid']} | {r['size']} | {r['samples']} "
                     f"| {sync} | {r['render_seconds']:.2f} | {r['wall_seconds']:.2f} |")
    ratios = ", ".join(f"{k} {v}x" for k, v in section["ratios_over_principled_render"].items())
    return lines + ["", f"Render time over Principled's at equal samples (default matrix): {ratios}."]


# --- Bake times --------------------------------------------------------------------------

def synthetic_hdri(path: Path, width: int) -> None:
    """A smooth sky-and-ground gradient with a small sun of radiance 2000."""
    import numpy as np
    from addon.core.hdri import write_float_exr
    h = width // 2
    e = (0.5 - (np.arange(h) + 0.5) / h)[:, None] * np.pi
    s = (np.arange(width) + 0.5)[None, :] / width
    sky = np.where(e > 0, 0.6 + 0.4 * np.sin(e), 0.2 + 0.05 * np.cos(8 * np.pi * s))
    img = np.repeat(sky[:, :, None], 3, axis=2).astype(np.float32) * np.array([0.9, 1.0, 1.1],
                                                                            dtype=np.float32)
    r = max(1, width // 512)
    img[h // 4 - r: h // 4 + r, width // 3 - r: width // 3 + r] = 2000.0
    write_float_exr(path, img)


def bench_bake() -> dict:
    from addon.core import ibl_bake
    from addon.blender.paths import bundled_hdri
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        os.environ["CTLAB_CACHE"] = str(tmp / "cache")
        start = time.perf_counter()
        for g in ibl_bake.G_MODELS:
            ibl_bake.dfg_path(g)
        dfg_seconds = round(time.perf_counter() - start, 2)
        print(f"DFG tables (once per cache): {dfg_seconds} s", flush=True)
        inputs = [(name, bundled_hdri(name)) for name in BUNDLED]
        for width in (2048, 4096):
            path = tmp / f"synthetic-{width}.exr"
            synthetic_hdri(path, width)
            inputs.append((f"synthetic {width}x{width // 2}", path))
        for name, path in inputs:
            t = time.perf_counter()
            folder = ibl_bake.bake(path)
            cold = time.perf_counter() - t
            t = time.perf_counter()
            ibl_bake.bake(path)
            cached = time.perf_counter() - t
            info = json.loads((folder / ibl_bake.INFO_FILE).read_text())
            w, h = info["source_size"]
            rows.append({"hdri": name, "size": f"{w}x{h}", "megapixels": round(w * h / 1e6, 3),
                         "bake_seconds": round(cold, 3), "cached_seconds": round(cached, 4),
                         "stages": info["timings"]})
            print(rows[-1], flush=True)
            shutil.rmtree(folder)
    one_k = [r["bake_seconds"] for r in rows if r["size"] == "1024x512"]
    return {"dfg_seconds_once": dfg_seconds, "rows": rows,
            "bundled_1k_mean_seconds": round(sum(one_k) / len(one_k), 3),
            "bundled_1k_max_seconds": max(one_k)}


def bake_table(section: dict) -> list:
    lines = ["| HDRI | size | bake (s) | cached (s) | level 1 (s) | level 0 copy (s) |",
             "|---|---|---|---|---|---|"]
    for r in section["rows"]:
        st = r["stages"]
        lines.append(f"| {r['hdri']} | {r['size']} | {r['bake_seconds']:.2f} | "
                     f"{r['cached_seconds']:.3f} | {st['specular_1.exr']:.2f} | "
                     f"{st['specular_0.exr']:.2f} |")
    return lines + ["", f"Bundled 1024x512 HDRIs: mean {section['bundled_1k_mean_seconds']} s, "
                        f"max {section['bundled_1k_max_seconds']} s per bake. The DFG tables "
                        f"(independent of the HDRI) take {section['dfg_seconds_once']} s once "
                        f"per cache."]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true", help="smaller render sizes (a smoke run)")
    ap.add_argument("--only", choices=("render", "bake"), help="run one section, keep the other")
    args = ap.parse_args()
    results = {}
    if args.only and (OUT / "results.json").is_file():
        results = json.loads((OUT / "results.json").read_text())
    results["machine"] = {"cpu_count": os.cpu_count(), "platform": platform.platform(),
                          "blender": bpy.app.version_string}
    if args.only in (None, "render"):
        results["render"] = bench_render(args.quick)
    if args.only in (None, "bake"):
        results["bake"] = bench_bake()
    OUT.mkdir(exist_ok=True)
    (OUT / "results.json").write_text(json.dumps(results, indent=2))
    lines = []
    if "render" in results:
        lines += ["### Render", ""] + render_table(results["render"]) + [""]
    if "bake" in results:
        lines += ["### Bake (split-sum files)", ""] + bake_table(results["bake"]) + [""]
    (OUT / "results.md").write_text("\n".join(lines))
    print("\n".join(lines))


if __name__ == "__main__":
    main()
