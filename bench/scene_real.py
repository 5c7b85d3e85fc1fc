"""The cost of the model in a real scene: a product shot with every material converted.

    ./scripts/dev.sh bench --only scene-real [--quick] [--pairs N] [--config NAME ...]

The scene (built once, in a child process): a
floor with an image texture as its colour, a vase (white dielectric, its roughness an image
texture), a polished gold sphere, a rough copper cube, a red plastic sphere; an Area light and
Blender's forest.exr world; a perspective camera; 240x180 px, 64 samples. Five Principled BSDF
materials (Blender's default Multiscatter GGX), two image textures.

Each render runs in a fresh process, Principled and converted alternately (P C P C ..., so a
drift of the machine's load falls on both): the converted side converts every Principled
material with the conversion the operator runs (``blender.convert.principled_to_model``, the
scene transport) and renders. Per implementation (node group on SVM; OSL with Cycles' OSL
shading on for both sides) and per setting:

- ``default``: the materials as converted (Cook-Torrance G, Disney diffuse, energy from the
  distribution: compensated);
- ``exact``: Principled's GGX, and the model's own closures (Smith G, Lambert, energy none),
  where the model needs no correction.

The ratio is the median over pairs of converted / Principled of Cycles' render time (the path
tracing, from the EXR's metadata); the sync time (the scene and shaders, OSL's compile and
optimisation) and the conversion's time are given beside it. Writes bench/results.json's
"scene-real" section and its table in bench/results.md (``--no-write``: prints the table
only). Its child processes (``child_main``) also serve bench/scene_cost.py and
bench/scene_samples.py.
"""

from __future__ import annotations

import json
import os
import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))  # in a child: bench.common, addon
from bench.common import child  # noqa: E402

SECTION = "scene-real"
SCENE = {"size": 240, "samples": 64}
QUICK = {"size": 64, "samples": 4}
CONFIGS = {  # name -> (implementation, OSL shading, settings)
    "nodes default": ("nodes", False, "default"),
    "nodes exact": ("nodes", False, "exact"),
    "osl default": ("osl", True, "default"),
    "osl exact": ("osl", True, "exact"),
}
EXACT = {"g_model": "smith_ggx_correlated", "diffuse_model": "lambert", "energy": "none"}


# --- In the child process (bpy) ---------------------------------------------------------


def _child_build(path: str) -> None:
    """The product shot, saved to ``path`` with its two textures packed."""
    import bpy
    import mathutils
    import numpy as np

    from addon.blender import compat

    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y = 640, 480

    def image(name, pixels):
        h, w = pixels.shape[:2]
        img = bpy.data.images.new(name, w, h, alpha=False)
        img.pixels.foreach_set(np.dstack([pixels, np.ones((h, w, 1))]).astype(np.float32).ravel())
        img.pack()
        return img

    y, x = np.mgrid[0:128, 0:128] / 128.0
    checker = ((np.floor(x * 8) + np.floor(y * 8)) % 2)[..., None]
    wood = 0.35 + 0.25 * checker + 0.08 * np.sin(40 * x + 6 * np.sin(9 * y))[..., None]
    floor_colour = image("floor_colour", wood * np.array([0.9, 0.6, 0.35]))
    streaks = 0.2 + 0.5 * (0.5 + 0.5 * np.sin(30 * y + 3 * np.sin(7 * x)))
    vase_rough = image("vase_roughness", np.repeat(streaks[..., None], 3, axis=2))

    def principled(name, colour, metallic, roughness):
        mat = bpy.data.materials.new(name)
        compat.use_nodes(mat)
        bsdf = mat.node_tree.nodes["Principled BSDF"]
        bsdf.inputs["Base Color"].default_value = (*colour, 1.0)
        bsdf.inputs["Metallic"].default_value = metallic
        bsdf.inputs["Roughness"].default_value = roughness
        return mat, bsdf

    def textured(mat, bsdf, img, socket):
        tex = mat.node_tree.nodes.new("ShaderNodeTexImage")
        tex.image = img
        if socket == "Roughness":
            img.colorspace_settings.name = "Non-Color"
        mat.node_tree.links.new(tex.outputs["Color"], bsdf.inputs[socket])

    def add(kind, name, mat, **kw):
        getattr(bpy.ops.mesh, f"primitive_{kind}_add")(**kw)
        obj = bpy.context.object
        obj.name = name
        if kind != "plane":
            bpy.ops.object.shade_smooth()
        obj.data.materials.append(mat)
        return obj

    floor, bsdf = principled("Floor", (0.8, 0.8, 0.8), 0.0, 0.5)
    textured(floor, bsdf, floor_colour, "Base Color")
    add("plane", "Floor", floor, size=12)
    vase, bsdf = principled("Vase", (0.85, 0.85, 0.82), 0.0, 0.3)
    textured(vase, bsdf, vase_rough, "Roughness")
    add("cylinder", "Vase", vase, vertices=64, radius=0.45, depth=1.6, location=(-1.2, 0.6, 0.8))
    gold, _ = principled("Polished Gold", (1.0, 0.77, 0.34), 1.0, 0.08)
    add("uv_sphere", "Gold", gold, segments=64, ring_count=32, radius=0.55, location=(0, 0, 0.55))
    copper, _ = principled("Rough Copper", (0.95, 0.64, 0.54), 1.0, 0.6)
    add("cube", "Copper", copper, size=0.8, location=(1.2, 0.5, 0.4))
    plastic, _ = principled("Red Plastic", (0.7, 0.05, 0.04), 0.0, 0.35)
    add("uv_sphere", "Plastic", plastic, segments=64, ring_count=32, radius=0.35,
        location=(0.6, -0.9, 0.35))  # fmt: skip

    def aim(obj, target):
        d = mathutils.Vector(target) - obj.location
        obj.rotation_euler = d.to_track_quat('-Z', 'Y').to_euler()

    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    scene.collection.objects.link(cam)
    cam.location = (0.5, -5.5, 2.4)
    aim(cam, (0, 0, 0.5))
    scene.camera = cam
    light = bpy.data.objects.new("Key Area", bpy.data.lights.new("Key Area", 'AREA'))
    light.data.energy, light.data.size = 250.0, 2.0
    scene.collection.objects.link(light)
    light.location = (-3, -3, 4)
    aim(light, (0, 0, 0.5))
    world = bpy.data.worlds.new("Forest")
    compat.use_nodes(world)
    nt = world.node_tree
    nt.nodes.clear()
    env = nt.nodes.new("ShaderNodeTexEnvironment")
    env.image = bpy.data.images.load(
        os.path.join(
            bpy.utils.system_resource('DATAFILES', path='studiolights/world'), "forest.exr"
        )
    )
    bg = nt.nodes.new("ShaderNodeBackground")
    out = nt.nodes.new("ShaderNodeOutputWorld")
    nt.links.new(env.outputs["Color"], bg.inputs["Color"])
    nt.links.new(bg.outputs["Background"], out.inputs["Surface"])
    scene.world = world
    bpy.ops.wm.save_as_mainfile(filepath=path, compress=False)


def _child_render(
    blend: str, side: str, config: str, out: str, size: int, samples: int, after_convert=None
) -> None:
    """One render: Principled or every material converted (then ``after_convert(info)``, if
    given: bench/scene_cost.py's variants, bench/scene_samples.py's samples and seed);
    prints its timings as JSON."""
    import bpy

    from addon.blender import comparison_render, convert, model_node, node_group, renderer
    from addon.blender.user_blend import open_blend
    from addon.jobs.scene_job import SceneJob

    impl, osl, setting = CONFIGS[config]
    scene = open_blend(Path(blend), os.devnull)
    mats = [m for m in bpy.data.materials if convert.surface_principled(m) is not None]
    if setting == "exact":  # single-scatter GGX: the model's own closures, energy none
        for mat in mats:
            convert.surface_principled(mat).distribution = 'GGX'
    info = {"side": side, "config": config, "materials": len(mats)}
    if side == "converted":
        start = time.perf_counter()
        for mat in mats:
            convert.principled_to_model(mat, scene, impl)
            if setting == "exact":
                node = model_node.find(mat)
                for key, value in EXACT.items():
                    model_node.set_option(node, key, value)
        info["convert_seconds"] = round(time.perf_counter() - start, 3)
        info["energy"] = sorted({model_node.get_option(model_node.find(m), "energy") for m in mats})
        group = bpy.data.node_groups.get(node_group.load_description()["group"]["name"])
        info["group_nodes"] = None if group is None else _count_nodes(group)
        if after_convert is not None:
            after_convert(info)
    seed = info.get("seed", 0)  # a hook may ask for another seed (bench/scene_samples.py)
    job = SceneJob(blend=Path(blend), out=Path(out), size=size, samples=samples, seed=seed)
    comparison_render.set_comparison_render(
        scene, scene.camera, job.size, job.samples, job.seed, osl, job.notes
    )
    d = renderer.render(scene, Path(out), {"side": side}, os.devnull)
    if info.get("layers"):  # a hook asks for the Material Index pass (bench/scene_depth.py)
        result = bpy.data.images["Render Result"]
        comparison_render.save_layers(scene, result, Path(out) / "layers.exr")
    info.update({k: d.get(k) for k in ("render_seconds", "sync_seconds", "cycles_render_seconds")})
    print("RESULT " + json.dumps(info), flush=True)


def _count_nodes(tree, seen=None) -> int:
    """Nodes in a group and the groups it holds (each counted once)."""
    seen = {} if seen is None else seen
    if tree.name not in seen:
        seen[tree.name] = len(tree.nodes)
        for node in tree.nodes:
            if node.bl_idname == "ShaderNodeGroup" and node.node_tree is not None:
                _count_nodes(node.node_tree, seen)
    return sum(seen.values())


# --- The driver -------------------------------------------------------------------------


def bench_scene_real(quick: bool, work: Path, pairs: int = 2, configs=None) -> dict:
    """Render every configuration's pairs, alternating sides; the section's data."""
    scene = QUICK if quick else SCENE
    blend = work / "product_shot.blend"
    child(SECTION, "build", blend)
    runs, ratios, warm = {}, {}, {}
    for impl in dict.fromkeys(CONFIGS[c][0] for c in configs or CONFIGS):
        # warm-up, not counted: the HDRI's bake and the node group's first build (cached)
        config = next(c for c in configs or CONFIGS if CONFIGS[c][0] == impl)
        warm[impl] = child(
            SECTION, "render", blend, "converted", config, work / f"warm-{impl}", 16, 1
        )
    for config in configs or CONFIGS:
        runs[config] = []
        for i in range(pairs):
            order = ("principled", "converted") if i % 2 == 0 else ("converted", "principled")
            for side in order:
                folder = work / f"{config.replace(' ', '-')}-{i}-{side}"
                r = child(
                    SECTION, "render", blend, side, config, folder, scene["size"], scene["samples"]
                )
                r["load"] = round(os.getloadavg()[0], 2)
                runs[config].append(r)
                print(
                    f"scene-real: {config} {side}: {r['cycles_render_seconds']:.2f} s "
                    f"(sync {r['sync_seconds']:.2f} s, load {r['load']})",
                    flush=True,
                )
        p = [r["cycles_render_seconds"] for r in runs[config] if r["side"] == "principled"]
        c = [r["cycles_render_seconds"] for r in runs[config] if r["side"] == "converted"]
        ratios[config] = round(statistics.median(b / a for a, b in zip(p, c)), 3)
    return {
        "scene": dict(scene, pairs=pairs, materials=5, textures=2, lights="Area + forest.exr"),
        "runs": runs,
        "ratio": ratios,
        "warm_up": warm,
    }


def scene_real_table(section: dict) -> list:
    sc = section["scene"]
    lines = [
        f"A product shot (floor with a colour texture, a vase with a roughness texture, "
        f"polished gold, rough copper, red plastic: {sc['materials']} Principled materials, "
        f"{sc['textures']} image textures; {sc['lights']}), {sc['size']} px wide, "
        f"{sc['samples']} samples, Cycles CPU. Every material converted (scene transport). "
        f"Each render a fresh process, the sides alternating; ratio = median over "
        f"{sc['pairs']} pairs of Cycles' render (path tracing) time; load = the 1-minute "
        "load average at the end of each render.",
        "",
        "| implementation, settings | converted / Principled | Principled render s | "
        "converted render s | sync s (P / C) | conversion s | group nodes | load |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for config, runs in section["runs"].items():
        p = [r for r in runs if r["side"] == "principled"]
        c = [r for r in runs if r["side"] == "converted"]

        def secs(rs, key):
            return ", ".join(f"{r[key]:.2f}" for r in rs)

        nodes = c[0].get("group_nodes") if c else None
        lines.append(
            f"| {config} | **{section['ratio'][config]:.2f}x** | "
            f"{secs(p, 'cycles_render_seconds')} | {secs(c, 'cycles_render_seconds')} | "
            f"{secs(p, 'sync_seconds')} / {secs(c, 'sync_seconds')} | "
            f"{secs(c, 'convert_seconds')} | {nodes if nodes is not None else '–'} | "
            f"{', '.join(str(r['load']) for r in runs)} |"
        )
    return lines


def child_main(args: list, after_convert=None) -> None:
    """A child process: ``build PATH`` or ``render BLEND SIDE CONFIG OUT SIZE SAMPLES [EXTRA
    ...]``; a converted render runs ``after_convert(*EXTRA)`` (a function of the render's info,
    or None) after its conversion (bench/scene_cost.py's variants, bench/scene_samples.py's
    counts)."""
    import bpy

    bpy.utils.expose_bundled_modules()
    if args[0] == "build":
        _child_build(args[1])
    else:
        blend, side, config, out, size, samples = args[1:7]
        hook = after_convert(*args[7:]) if after_convert and side == "converted" else None
        _child_render(blend, side, config, out, int(size), int(samples), hook)
    sys.stdout.flush()
    os._exit(0)  # bpy as a module can hang at exit (tests/conftest.py)
