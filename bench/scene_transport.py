"""The scene transport in a real scene: the demo scene's spheres with each material, against
Principled BSDF, in one process; and the world bake of a Sky Texture (scripts/bench.py
--only scene)."""

import os
import statistics
import tempfile
import time
from pathlib import Path

import bpy

# The sphere's material in the demo scene (addon/blender/demo_scene.py): Principled BSDF (the
# denominator), and the model's scene transport with exact closures, with the correction, and
# as the node group.
# Each: (Cycles' shading system, the model's implementation or None for Principled, options).
# An OSL material turns Cycles' OSL shading on for the whole scene, so Principled is measured
# on both systems: the material's own cost is the ratio at the same shading system.
SCENE_VARIANTS = {
    "principled": ("svm", None, {}),
    "principled (osl shading)": ("osl", None, {}),
    "osl scene (exact closures)": (
        "osl",
        "osl",
        {"g_model": "smith_ggx_correlated", "diffuse_model": "lambert"},
    ),
    "osl scene (correction)": (
        "osl",
        "osl",
        {"g_model": "cook_torrance", "diffuse_model": "disney"},
    ),
    "nodes scene": (
        "svm",
        "nodes",
        {"g_model": "smith_ggx_correlated", "diffuse_model": "lambert", "ibl": "split_sum"},
    ),
}
SAME_SYSTEM = {"osl": "principled (osl shading)", "svm": "principled"}


def bench_scene(quick: bool, work: Path) -> dict:
    """Render time of the demo scene (a metal sphere and an orange sphere beside a cube, a
    floor, an area light, an emissive panel, forest.exr) with each material for both spheres,
    against Principled, in one process: each variant warmed up once (the OSL shader's
    compilation), then rounds in alternating order; ratio = the median over rounds. Also the
    world bake of a Sky Texture when the add-on has it."""
    from addon.blender import demo_scene, light_sync, materials, renderer
    from addon.core.model import ModelOptions

    size, samples, rounds = ((128, 96), 16, 1) if quick else ((320, 240), 64, 4)
    scene, sphere, other = demo_scene.build("hdri", *size)
    mats = {}
    for name, (_system, impl, model) in SCENE_VARIANTS.items():
        pair = []
        for obj, values, label in (
            (sphere, demo_scene.METAL, "metal"),
            (other, demo_scene.ORANGE, "orange"),
        ):
            if impl is None:
                pair.append(demo_scene.principled_for(values, f"{name} {label}"))
            else:
                mat = materials.model_material(
                    f"{name} {label}",
                    impl,
                    ModelOptions(light_transport="scene", **model),
                    **values,
                )
                demo_scene.set_material(obj, mat)
                light_sync.sync_material(mat, scene)
                pair.append(mat)
        mats[name] = pair

    def timed(name, samples_):
        demo_scene.set_material(sphere, mats[name][0])
        demo_scene.set_material(other, mats[name][1])
        system, impl, _model = SCENE_VARIANTS[name]
        shader = "osl" if system == "osl" else (impl or "principled")
        renderer.configure(scene, shader, "full", samples_, path_traced=True)
        d = renderer.render(
            scene, work / f"scene-{len(os.listdir(work))}", {"width": size[0], "height": size[1]}
        )
        return d["sync_seconds"] + d["cycles_render_seconds"]

    for name in SCENE_VARIANTS:
        timed(name, 1)  # warm-up: compile, load, build
    times = {name: [] for name in SCENE_VARIANTS}
    names = list(SCENE_VARIANTS)
    for i in range(rounds):
        for name in names if i % 2 == 0 else names[::-1]:
            times[name].append(timed(name, samples))
            print(f"scene: {name}: {times[name][-1]:.2f} s", flush=True)

    def ratio(name, over):
        return round(statistics.median(times[name]) / statistics.median(times[over]), 3)

    out = {
        "scene": {
            "size": list(size),
            "samples": samples,
            "rounds": rounds,
            "objects": "metal sphere + orange sphere (both the material timed) + red "
            "cube + floor + area light + emissive panel, forest.exr",
        },
        "seconds": {k: [round(t, 3) for t in v] for k, v in times.items()},
        "ratio_over_principled": {k: ratio(k, "principled") for k in times if k != "principled"},
        "ratio_same_shading": {
            k: ratio(k, SAME_SYSTEM[v[0]]) for k, v in SCENE_VARIANTS.items() if v[1] is not None
        },
    }
    try:
        from addon.blender import world_bake
    except ImportError:
        world_bake = None
    if world_bake is not None:
        demo_scene.build("sky", 64, 48)
        saved = os.environ.get("CTLAB_CACHE")
        with tempfile.TemporaryDirectory() as empty:  # cold: nothing cached
            os.environ["CTLAB_CACHE"] = empty
            try:
                start = time.perf_counter()
                world_bake.bake_world(bpy.context.scene.world, 1024)
                out["sky_bake_seconds_1k"] = round(time.perf_counter() - start, 2)
            finally:
                if saved is None:
                    os.environ.pop("CTLAB_CACHE", None)
                else:
                    os.environ["CTLAB_CACHE"] = saved
    return out


def scene_table(section: dict) -> list:
    sc = section["scene"]
    lines = [
        f"The demo scene ({sc['objects']}), {sc['size'][0]}x{sc['size'][1]} px, "
        f"{sc['samples']} samples, Cycles CPU, one process; render = Cycles' sync + "
        f"render; ratio = median over {sc['rounds']} alternating rounds.",
        "",
        "| the spheres' material | seconds | / Principled (SVM) | / Principled, same "
        "shading system |",
        "|---|---|---|---|",
    ]
    for name, secs in section["seconds"].items():
        ratio = section["ratio_over_principled"].get(name)
        same = section["ratio_same_shading"].get(name)
        lines.append(
            f"| {name} | {', '.join(f'{t:.2f}' for t in secs)} | "
            + ("1" if ratio is None else f"{ratio:.2f}x")
            + " | "
            + ("–" if same is None else f"**{same:.2f}x**")
            + " |"
        )
    if "sky_bake_seconds_1k" in section:
        lines += [
            "",
            f"World bake of a Sky Texture at 1024x512: "
            f"**{section['sky_bake_seconds_1k']:.2f} s** (cold).",
        ]
    return lines
