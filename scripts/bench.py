"""Benchmark: the OSL Cook-Torrance matrix against Principled BSDF at equal samples.

Writes bench/results.json and bench/results.md (the README's table). Each figure is from one
run on this machine; Cycles' synchronisation (scene + shader compile) is reported apart from
its render time.

    .venv/bin/python scripts/bench.py [--quick]
"""

import argparse
import json
import os
import platform
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
import bpy  # noqa: E402

bpy.utils.expose_bundled_modules()
from addon import cli  # noqa: E402
from addon.params import ModelOptions  # noqa: E402
from addon.scene_builder import MatrixSettings  # noqa: E402


def one(shader, grid, size, samples, work):
    s = MatrixSettings(rows=grid, cols=grid, width=size, height=size, shader=shader,
                       model=ModelOptions(view="full"))
    start = time.perf_counter()
    d = cli.render_one(s, work / f"{shader}-{grid}-{size}-{samples}", samples, verbose=False)
    return {"shader": shader, "grid": f"{grid}x{grid}", "size": size, "samples": samples,
            "env_samples": s.model.env_samples, "wall_seconds": round(time.perf_counter() - start, 2),
            "sync_seconds": d.get("sync_seconds"), "render_seconds": d.get("cycles_render_seconds")}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true", help="smaller sizes (a smoke run)")
    args = ap.parse_args()
    main_cfg = (7, 256, 16) if args.quick else (7, 512, 64)
    grids = (3, 7, 11)
    sizes = (128, 256) if args.quick else (128, 256, 512)
    scale_samples = 16
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        # the headline: default matrix at equal samples
        for shader in ("osl", "principled"):
            rows.append(dict(one(shader, *main_cfg, work), case="default matrix"))
            print(rows[-1], flush=True)
        for g in grids:
            for shader in ("osl", "principled"):
                rows.append(dict(one(shader, g, 256, scale_samples, work), case="grid"))
                print(rows[-1], flush=True)
        for size in sizes:
            for shader in ("osl", "principled"):
                rows.append(dict(one(shader, 7, size, scale_samples, work), case="resolution"))
                print(rows[-1], flush=True)
    osl, ref = rows[0], rows[1]
    result = {"machine": {"cpu_count": os.cpu_count(), "platform": platform.platform(),
                          "blender": bpy.app.version_string},
              "ratio_osl_over_principled_render": round(osl["render_seconds"] / ref["render_seconds"], 2),
              "ratio_osl_over_principled_wall": round(osl["wall_seconds"] / ref["wall_seconds"], 2),
              "rows": rows}
    out = ROOT / "bench"
    out.mkdir(exist_ok=True)
    (out / "results.json").write_text(json.dumps(result, indent=2))
    lines = ["| case | shader | grid | size | samples | sync (s) | render (s) | wall (s) |",
             "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['case']} | {r['shader']} | {r['grid']} | {r['size']} | {r['samples']} "
                     f"| {r['sync_seconds']:.2f} | {r['render_seconds']:.2f} | {r['wall_seconds']:.2f} |")
    lines.append("")
    lines.append(f"OSL / Principled render time at equal samples (default matrix): "
                 f"{result['ratio_osl_over_principled_render']}x "
                 f"(wall, with set-up and compile: {result['ratio_osl_over_principled_wall']}x).")
    (out / "results.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
