"""The correction's depth (docs/model.md "The correction's depth"): what the default
Correction Depth 2 costs in fidelity, and saves in render time, against the correction at
every depth (1024).

    ./scripts/dev.sh bench --only scene-depth [--quick] [--pairs N]

bench/scene_real.py's product shot, every material converted with the default settings, to
each implementation. Per implementation and per seed (``pairs`` seeds, at least 2), a render
at depth 2 and one at depth 1024, in alternating order, each a fresh process. Fidelity: per
material (its Material Index pass), the mean CIEDE2000 of the displayed images between depth
2 and depth 1024 at seed 0; beside it the noise floor, depth 1024 at seed 1 against seed 0
(what noise alone gives: the two compared renders share their seed, so a mean below the
floor is usual). Time: the median over seeds of depth 2's render time over depth 1024's.
"""

from __future__ import annotations

import statistics
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
from bench import scene_real  # noqa: E402
from bench.common import child  # noqa: E402

SECTION = "scene-depth"
CONFIGS = ("nodes default", "osl default")
DEPTHS = (2, 1024)  # the default, and every hit


def with_depth(depth: str, seed: str):
    """The function run after the conversion in a render's process: every converted
    material's Correction Depth, its Material Index (by name, from 1), the render's seed."""

    def apply(info: dict) -> None:
        import bpy

        from addon.blender import model_node

        converted = sorted(
            (m for m in bpy.data.materials if model_node.find(m) is not None),
            key=lambda m: m.name,
        )
        for i, mat in enumerate(converted, 1):
            model_node.transport_input(
                model_node.find(mat), "correction_depth"
            ).default_value = int(depth)
            mat.pass_index = i
        index = {m.name: m.pass_index for m in converted}
        info.update(depth=int(depth), seed=int(seed), layers=True, pass_index=index)

    return apply


def bench_scene_depth(quick: bool, work: Path, pairs: int = 2) -> dict:
    """Render each implementation at both depths and ``pairs`` seeds; the section's data."""
    from addon.core.compare import ciede2000, read_image, read_material_index, srgb_to_lab

    scene = scene_real.QUICK if quick else scene_real.SCENE
    blend = work / "product_shot_depth.blend"
    child(scene_real.SECTION, "build", blend)
    data = {"scene": dict(scene, seeds=max(pairs, 2)), "configs": {}}
    for config in CONFIGS:
        # warm-up, not counted: the HDRI's bake and the node group's first build (cached)
        child(scene_real.SECTION, "render", blend, "converted", config, work / "depth-warm", 16, 1)
        runs = {}
        for seed in range(max(pairs, 2)):
            for depth in DEPTHS if seed % 2 == 0 else DEPTHS[::-1]:
                folder = work / f"depth-{config.replace(' ', '-')}-{depth}-{seed}"
                args = ("render", blend, "converted", config, folder, scene["size"])
                r = child(SECTION, *args, scene["samples"], depth, seed)
                runs[depth, seed] = (folder, r)
                print(
                    f"scene-depth: {config} depth {depth} seed {seed}: "
                    f"{r['cycles_render_seconds']:.2f} s",
                    flush=True,
                )
        lab = {k: srgb_to_lab(read_image(f / "render.png")) for k, (f, _) in runs.items()}
        index = read_material_index(runs[2, 0][0] / "layers.exr")
        de = ciede2000(lab[2, 0], lab[1024, 0])
        floor = ciede2000(lab[1024, 1], lab[1024, 0])
        materials = {}
        for name, i in runs[2, 0][1]["pass_index"].items():
            mask = index == i
            if mask.any():
                materials[name] = {
                    "pixels": int(mask.sum()),
                    "mean_ciede2000": round(float(de[mask].mean()), 4),
                    "noise_floor": round(float(floor[mask].mean()), 4),
                }
        seconds = {d: [runs[d, s][1]["cycles_render_seconds"] for s in range(2)] for d in DEPTHS}
        data["configs"][config] = {
            "materials": materials,
            "seconds": {str(d): v for d, v in seconds.items()},
            "time_ratio": round(
                statistics.median(a / b for a, b in zip(seconds[2], seconds[1024])), 3
            ),
        }
    return data


def scene_depth_table(section: dict) -> list:
    sc = section["scene"]
    lines = [
        f"bench/scene_real.py's product shot, {sc['size']} px wide, {sc['samples']} samples, "
        f"every material converted (default settings). Correction Depth 2 (the default: the "
        f"correction at camera hits and the first bounce) against 1024 (every hit): per "
        f"material, the mean CIEDE2000 between the two (seed 0), beside the noise floor (depth "
        f"1024, seed 1 against seed 0); time: median over {sc['seeds']} seeds of depth 2's "
        "render time over depth 1024's, each render a fresh process.",
        "",
        "| implementation | material | pixels | mean CIEDE2000, depth 2 vs 1024 | noise floor |",
        "|---|---|---|---|---|",
    ]
    for config, c in section["configs"].items():
        for name, m in c["materials"].items():
            lines.append(
                f"| {config} | {name} | {m['pixels']} | **{m['mean_ciede2000']:.3f}** | "
                f"{m['noise_floor']:.3f} |"
            )
    lines += ["", "| implementation | render s, depth 2 | render s, depth 1024 | depth 2 / 1024 |"]
    lines.append("|---|---|---|---|")
    for config, c in section["configs"].items():
        s = c["seconds"]
        lines.append(
            f"| {config} | {', '.join(f'{x:.2f}' for x in s['2'])} | "
            f"{', '.join(f'{x:.2f}' for x in s['1024'])} | **{c['time_ratio']:.2f}x** |"
        )
    return lines
