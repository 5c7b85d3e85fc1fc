"""Equal error: each Cycles renderer's error against its own converged image as a function
of render time, and the time each needs to reach Principled's error (scripts/bench.py
--only error). Converged images are cached in out/bench-cache (keyed by Blender's version,
the renderer, the scene and the model's sources)."""

import functools
import hashlib
import shutil
from pathlib import Path

import bpy
import numpy as np

from addon.core.compare import cell_mask, ciede2000, load_render, srgb_to_lab
from addon.core.files import atomic_folder
from bench.common import CACHE, ENV_VARIANTS, RENDERERS, ROOT, render

# The reference integrator's variants are measured against its own converged image
CONVERGED_AS = dict.fromkeys(ENV_VARIANTS, "osl reference")

CLASSES = {
    "smooth metal": lambda m, s: m >= 0.5 and s >= 0.5,
    "rough metal": lambda m, s: m >= 0.5 and s < 0.5,
    "smooth dielectric": lambda m, s: m < 0.5 and s >= 0.5,
    "rough dielectric": lambda m, s: m < 0.5 and s < 0.5,
}


@functools.cache
def _sources_digest() -> str:
    h = hashlib.sha256()
    for p in (
        sorted((ROOT / "osl").glob("*.[oh]*"))
        + sorted((ROOT / "node_groups").glob("*.toml"))
        + sorted((ROOT / "addon").rglob("*.py"))
    ):
        h.update(p.read_bytes())
    return h.hexdigest()[:12]


def converged(name: str, grid: str, size: int, samples: int) -> Path:
    """The renderer's own converged image (seed 1), cached across runs."""
    key = f"{bpy.app.version_string}-{name}-{grid}-{size}-{samples}-{_sources_digest()}"
    folder = CACHE / key.replace(" ", "_").replace("(", "").replace(")", "")
    if not (folder / "scene.json").is_file():
        shutil.rmtree(folder, ignore_errors=True)

        def fill(stage):
            row = render(name, stage, grid, size, samples, seed=1)
            print(f"converged {name}: {samples} samples, {row['render_seconds']:.1f} s", flush=True)

        atomic_folder(folder, fill)
    return folder


def errors(folder: Path, reference: Path) -> dict:
    """RMSE of the displayed image (sRGB, 0..1) and mean CIEDE2000 against the converged
    image, over the spheres of each class. Displayed, not linear: a sun's glint on a mirror
    sphere covers a pixel at radiance in the thousands, and the linear RMSE of the smooth
    metals is that one pixel's luck, not the noise a viewer sees."""
    lin, disp, scene = load_render(folder)
    lin_r, disp_r, _ = load_render(reference)
    de = ciede2000(srgb_to_lab(disp), srgb_to_lab(disp_r))
    out = {}
    for cls, test in CLASSES.items():
        mask = np.zeros(lin.shape[:2], dtype=bool)
        for cell in scene["cells"]:
            if test(cell["metallic"], cell["smoothness"]):
                mask |= cell_mask(lin.shape, cell)
        d = (disp[mask] - disp_r[mask]).astype(np.float64)
        out[cls] = {"rmse": float(np.sqrt(np.mean(d**2))), "mean_de": float(de[mask].mean())}
    return out


def bench_error(quick: bool, work: Path) -> dict:
    """Each Cycles renderer at 8..128 samples against its own converged image (1024 samples,
    another seed). Monte Carlo error falls as 1/sqrt(time), so RMSE x sqrt(render time) is a
    renderer's cost constant per class; the time to reach an equal error, over Principled's,
    is the square of the ratio of those constants, taken at the highest sample count (where
    the fixed sync cost weighs least). The converged image's own noise (1/8 of the error's
    variance at 128 samples) is left in: it flatters no renderer. The reference integrator
    is also measured with 1, 2 and 8 samples per shading point against the same converged
    image (its default is 4); that image's own noise then weighs more against the less noisy
    variants, so 8 samples is, if anything, flattered less than 1."""
    grid, size = "7x7", 256
    counts = (8, 32) if quick else (8, 16, 32, 64, 128)
    ref_samples = 256 if quick else 1024
    names = [n for n in RENDERERS if "eevee" not in n] + ([] if quick else list(ENV_VARIANTS))
    series = {}
    for name in names:
        ref = converged(CONVERGED_AS.get(name, name), grid, size, ref_samples)
        rows = []
        for n in counts:
            r = render(name, work / f"err-{name}-{n}".replace(" ", "_"), grid, size, n)
            rows.append(
                {
                    "samples": n,
                    "render_seconds": r["render_seconds"],
                    "errors": errors(Path(r["folder"]), ref),
                }
            )
            shutil.rmtree(r["folder"])
        series[name] = rows
        print(
            f"error series {name}: "
            + ", ".join(f"{row['samples']}spp {row['render_seconds']:.1f}s" for row in rows),
            flush=True,
        )
    equal_error = {}
    for name in names:
        last, base = series[name][-1], series["principled"][-1]
        equal_error[name] = {}
        for cls in CLASSES:
            k = last["errors"][cls]["rmse"] * last["render_seconds"] ** 0.5
            k0 = base["errors"][cls]["rmse"] * base["render_seconds"] ** 0.5
            equal_error[name][cls] = round((k / k0) ** 2, 3)
    return {
        "scene": {
            "grid": grid,
            "size": size,
            "converged_samples": ref_samples,
            "samples": list(counts),
        },
        "series": series,
        "time_at_equal_rmse_over_principled": equal_error,
    }


def error_table(section: dict) -> list:
    sc = section["scene"]
    lines = [
        f"Scene: {sc['grid']} spheres, {sc['size']} px, forest.exr; each renderer against "
        f"its own converged image ({sc['converged_samples']} samples, another seed). "
        "Time to reach the same RMSE as Principled, over Principled's (from RMSE x "
        "sqrt(render time) at the highest sample count):",
        "",
        "| renderer | " + " | ".join(CLASSES) + " |",
        "|---|" + "---|" * len(CLASSES),
    ]
    for name, by in section["time_at_equal_rmse_over_principled"].items():
        lines.append(f"| {name} | " + " | ".join(f"{by[c]:.3f}x" for c in CLASSES) + " |")
    lines += [
        "",
        "RMSE (displayed sRGB) and mean CIEDE2000 against the converged image, by samples "
        "(render seconds):",
        "",
        "| renderer | samples | seconds | " + " | ".join(f"{c} RMSE / ΔE" for c in CLASSES) + " |",
        "|---|---|---|" + "---|" * len(CLASSES),
    ]
    for name, rows in section["series"].items():
        for row in rows:
            cells = " | ".join(
                f"{row['errors'][c]['rmse']:.4f} / {row['errors'][c]['mean_de']:.2f}"
                for c in CLASSES
            )
            lines.append(f"| {name} | {row['samples']} | {row['render_seconds']:.2f} | {cells} |")
    return lines
