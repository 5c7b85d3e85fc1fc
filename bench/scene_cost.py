"""Where the converted product shot's render time goes: the node group (default settings) with
one part of it taken out at a time.

    ./scripts/dev.sh bench --only scene-cost [--quick] [--pairs N]

The scene, its conversion and the renders are
bench/scene_real.py's ("nodes default"); after the conversion each variant below changes the
converted group in the render's own process (never a file), and Cycles renders it. The
variants are not the model: they drop terms (the pictures are wrong on purpose), and exist
only to say what each part of the scene transport costs. Each render is a fresh process; per
pair the variants run in one order and then the reverse, Principled first and last, so a
drift of the machine's load falls on all. A variant's figure is the median of its render
times over the median of Principled's.
"""

from __future__ import annotations

import statistics
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
from bench import scene_real  # noqa: E402
from bench.common import child  # noqa: E402

SECTION = "scene-cost"
CONFIG = "nodes default"
# name -> what the variant takes out (the table's words)
VARIANTS = {
    "converted": "nothing: the converted scene as an artist renders it",
    "no world correction": "the correction group's Correction output (the world's "
    "split-sum emission): what is left is the closures and the per-light corrections",
    "no pre-filtered chains": "the five pre-filtered chains (Emission behind Mix Shader "
    "nodes) inside the correction: its tables and arithmetic stay",
    "chains without lookups": "the chains' Environment Texture lookups (each a constant "
    "colour): their Mix Shader and Emission nodes stay",
    "correction on camera rays only": "the world correction on every ray but camera rays "
    "(a Light Path gate)",
    "no per-light groups": "the key Sun's and the eight light slots' groups (the per-light "
    "correction and the lab's direct light)",
    "with residual pass": "nothing, and it adds the Residual Albedo Pass (off by default: "
    "light_sync.set_residual_pass), the materials' AOV Output and what computes it",
    "energy none": "the conversion's compensated energy (set to none after it: another model, "
    "without the multiple-scattering tables the correction's quantities read)",
    "closures alone": "the correction's Emission: the Metallic and Diffuse BSDFs and what "
    "feeds them",
}


def _groups():
    import bpy

    from addon.blender import node_group

    name = node_group.load_description()["group"]["name"]
    return (
        bpy.data.node_groups[name],
        bpy.data.node_groups[f"{name} Correction"],
        bpy.data.node_groups[f"{name} Pre-filtered"],
    )


def _unlink(tree, socket) -> None:
    for link in list(socket.links):
        tree.links.remove(link)


# The variants that take whole parts of the converted material out, and which parts
CUTS = {
    "no world correction": ("world",),
    "no per-light groups": ("lights",),
    "closures alone": ("world", "lights"),
}


def _cut(part: str, main, holder) -> None:
    """Take one part out: the correction group's world emission or the per-light groups'
    outputs."""
    if part == "world":
        _unlink(main, holder.outputs["Correction"])
    else:
        for node in main.nodes:
            tree = getattr(node, "node_tree", None)
            if tree is not None and tree.name.endswith(" Light"):
                for socket in node.outputs:
                    _unlink(main, socket)


def apply_variant(variant: str):
    """The function run after the conversion in a render's process (``after_convert``)."""

    def apply(info: dict) -> None:
        import bpy

        main, correction, chains = _groups()
        holder = next(n for n in main.nodes if getattr(n, "node_tree", None) == correction)
        if variant in CUTS:
            for part in CUTS[variant]:
                _cut(part, main, holder)
        elif variant == "no pre-filtered chains":
            out = next(n for n in chains.nodes if n.bl_idname == "NodeGroupOutput")
            _unlink(chains, out.inputs[0])
        elif variant == "chains without lookups":
            for node in [n for n in chains.nodes if n.bl_idname == "ShaderNodeTexEnvironment"]:
                rgb = chains.nodes.new("ShaderNodeRGB")
                rgb.outputs[0].default_value = (0.3, 0.3, 0.3, 1.0)
                for link in list(node.outputs["Color"].links):
                    chains.links.new(rgb.outputs[0], link.to_socket)
                chains.nodes.remove(node)
        elif variant == "correction on camera rays only":
            link = holder.outputs["Correction"].links[0]
            target = link.to_socket
            main.links.remove(link)
            path = main.nodes.new("ShaderNodeLightPath")
            gate = main.nodes.new("ShaderNodeMixShader")  # factor 0: the correction
            invert = main.nodes.new("ShaderNodeMath")
            invert.operation = "SUBTRACT"
            invert.inputs[0].default_value = 1.0
            main.links.new(path.outputs["Is Camera Ray"], invert.inputs[1])
            main.links.new(invert.outputs[0], gate.inputs["Fac"])
            main.links.new(holder.outputs["Correction"], gate.inputs[1])
            main.links.new(gate.outputs[0], target)
        elif variant == "with residual pass":
            from addon.blender import light_sync

            light_sync.set_residual_pass(bpy.context.scene, True)
        elif variant == "energy none":
            from addon.blender import model_node

            for mat in bpy.data.materials:
                node = model_node.find(mat)
                if node is not None:
                    model_node.set_option(node, "energy", "none")
        elif variant != "converted":
            raise SystemExit(f"bench: no variant {variant!r}")
        info["variant"] = variant

    return apply


def bench_scene_cost(quick: bool, work: Path, pairs: int = 2) -> dict:
    """Render Principled and every variant ``pairs`` times; the section's data."""
    scene = scene_real.QUICK if quick else scene_real.SCENE
    blend = work / "product_shot_cost.blend"
    child(scene_real.SECTION, "build", blend)
    # warm-up, not counted: the HDRI's bake and the node group's first build (cached)
    child(scene_real.SECTION, "render", blend, "converted", CONFIG, work / "cost-warm", 16, 1)
    times = {"principled": [], **{v: [] for v in VARIANTS}}
    for i in range(pairs):
        order = list(VARIANTS) if i % 2 == 0 else list(reversed(VARIANTS))
        for variant in ["principled", *order, "principled"]:
            side = "principled" if variant == "principled" else "converted"
            folder = work / f"cost-{i}-{len(times[variant])}-{variant.replace(' ', '-')}"
            args = ("render", blend, side, CONFIG, folder, scene["size"], scene["samples"])
            r = child(SECTION, *args, variant)
            times[variant].append(r["cycles_render_seconds"])
            print(f"scene-cost: {variant}: {r['cycles_render_seconds']:.2f} s", flush=True)
    base = statistics.median(times["principled"])
    return {
        "scene": dict(scene, pairs=pairs, config=CONFIG),
        "seconds": times,
        "ratio": {v: round(statistics.median(t) / base, 3) for v, t in times.items()},
    }


def scene_cost_table(section: dict) -> list:
    sc = section["scene"]
    lines = [
        f"bench/scene_real.py's product shot, {sc['size']} px wide, {sc['samples']} samples, "
        f"every material converted to the node group with the default settings; each variant "
        f"takes one part of the group out after the conversion (not the model: what a part "
        f"costs). {sc['pairs']} rounds, each a fresh process per render; ratio = median render "
        f"(path tracing) time over Principled's median.",
        "",
        "| variant | / Principled | render s | taken out |",
        "|---|---|---|---|",
    ]
    words = {"principled": "(Principled BSDF, the denominator)", **VARIANTS}
    for variant, secs in section["seconds"].items():
        lines.append(
            f"| {variant} | **{section['ratio'][variant]:.2f}x** | "
            f"{', '.join(f'{s:.2f}' for s in secs)} | {words[variant]} |"
        )
    return lines
