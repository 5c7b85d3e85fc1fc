"""The OSL shader's samples per shading point in the scene transport, at equal error: does the
correction need 4 BRDF + 4 environment samples (the lab's default), or does Cycles' own path
tracing carry the noise? And its two estimators: every technique of the world and of every
light per sample (the lab's), or one technique per sample (the one-sample model, the scene
transport's default: osl/ct_correction.h)?

    ./scripts/dev.sh bench --only scene-samples [--quick]

bench/scene_real.py's product shot, every
material converted to the OSL shader (its "osl default": Cook-Torrance G, Disney diffuse,
energy compensated), rendered with each estimator and ``Env Samples`` in ROWS at the scene's
samples per pixel, and once converged (CONVERGED_SAMPLES, every technique, 4 + 4, another
seed) as the reference they all estimate (the correction is unbiased with either estimator at
any count). Per row: Cycles' render time, over Principled's; the RMSE against the reference
(radiance clamped at 4, so a firefly does not decide it); MSE x time (the cost of a given
error) over that of the lab's 4 + 4; and the pixels below zero (the signed correction's
noise can make a sum negative). Each render a fresh process. The rules it informs:
core/model/rules.py DEFAULT_ENV_SAMPLES and the shader's One-Sample Correction.
"""

from __future__ import annotations

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
from bench import scene_real  # noqa: E402
from bench.common import child  # noqa: E402

SECTION = "scene-samples"
CONFIG = "osl default"
# (estimator, One-Sample Correction, Env Samples); the first is the cost's unit
ROWS = (
    ("every technique", 0, 4),
    ("every technique", 0, 1),
    ("one technique", 1, 1),
    ("one technique", 1, 2),
    ("one technique", 1, 4),
)
CONVERGED_SAMPLES, QUICK_CONVERGED = 1024, 32
REFERENCE_SEED = 7
CLAMP = 4.0


def with_samples(count: str, seed: str = "0", one_sample: str = "0"):
    """The hook run after the conversion (``after_convert``): every model node's Env Samples
    and One-Sample Correction, and the render's seed."""

    def apply(info: dict) -> None:
        import bpy

        from addon.blender import model_node

        for mat in bpy.data.materials:
            node = model_node.find(mat)
            if node is not None:
                node.inputs["Env Samples"].default_value = int(count)
                node.inputs["One-Sample Correction"].default_value = int(one_sample)
        info["env_samples"], info["seed"] = int(count), int(seed)

    return apply


def _image(folder: Path):
    import numpy as np

    from addon.core.compare import read_image

    return np.minimum(read_image(folder / "render.exr").astype(np.float64), CLAMP)


def bench_scene_samples(quick: bool, work: Path) -> dict:
    """The reference, Principled and each count once; the section's data."""
    import numpy as np

    import addon.blender  # noqa: F401  (exposes Blender's bundled OpenImageIO)
    from addon.core.compare import read_image

    scene = scene_real.QUICK if quick else scene_real.SCENE
    blend = work / "product_shot_samples.blend"
    child(scene_real.SECTION, "build", blend)
    size, spp = scene["size"], scene["samples"]
    converged = QUICK_CONVERGED if quick else CONVERGED_SAMPLES
    ref_dir = work / "samples-reference"
    args = ("render", blend, "converted", CONFIG, ref_dir, size, converged, 4, REFERENCE_SEED)
    child(SECTION, *args)
    reference = _image(ref_dir)
    folder = work / "samples-principled"
    principled = child(scene_real.SECTION, "render", blend, "principled", CONFIG, folder, size, spp)
    base = principled["cycles_render_seconds"]
    rows = {}
    for estimator, one_sample, count in ROWS:
        folder = work / f"samples-{one_sample}-{count}"
        args = ("render", blend, "converted", CONFIG, folder, size, spp, count, 0, one_sample)
        r = child(SECTION, *args)
        image = np.asarray(read_image(folder / "render.exr"), dtype=np.float64)
        mse = float(np.mean((_image(folder) - reference) ** 2))
        negative = int((image[..., :3] < 0).any(axis=-1).sum())
        rows[f"{estimator}, {count}"] = {
            "render_seconds": r["cycles_render_seconds"],
            "mse": mse,
            "negative_pixels": negative,
        }
        print(
            f"scene-samples: {estimator}, {count}: {r['cycles_render_seconds']:.2f} s, "
            f"mse {mse:.5f}, {negative} negative pixels",
            flush=True,
        )
    unit = rows[f"{ROWS[0][0]}, {ROWS[0][2]}"]
    cost4 = unit["mse"] * unit["render_seconds"]
    for row in rows.values():
        row["ratio"] = round(row["render_seconds"] / base, 3)
        row["rmse"] = round(row["mse"] ** 0.5, 5)
        row["cost_for_equal_error"] = round(row["mse"] * row["render_seconds"] / cost4, 3)
    return {
        "scene": dict(scene, converged=converged, config=CONFIG),
        "principled_seconds": base,
        "rows": {str(k): v for k, v in rows.items()},
    }


def scene_samples_table(section: dict) -> list:
    sc = section["scene"]
    lines = [
        f"bench/scene_real.py's product shot, {sc['size']} px wide, {sc['samples']} samples, "
        f"every material converted to the OSL shader (scene transport, default settings), with "
        f"the correction's estimator (every technique of the world and each light per sample, "
        f"or one technique per sample) and its Env Samples; reference: every technique, 4, at "
        f"{sc['converged']} samples, another seed. Principled renders it in "
        f"{section['principled_seconds']:.2f} s. Cost for equal error = MSE x render time over "
        f"that of the first row (radiance clamped at {CLAMP:g}); negative: pixels with a "
        f"channel below 0.",
        "",
        "| estimator, Env Samples | render s | / Principled | RMSE | cost for equal error "
        "| negative |",
        "|---|---|---|---|---|---|",
    ]
    for name, row in section["rows"].items():
        lines.append(
            f"| {name} | {row['render_seconds']:.2f} | **{row['ratio']:.2f}x** | "
            f"{row['rmse']:.4f} | {row['cost_for_equal_error']:.2f} | "
            f"{row.get('negative_pixels', '–')} |"
        )
    return lines
