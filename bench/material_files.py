"""What a converted material costs before the first sample and in the saved file: Cycles'
synchronisation (for OSL, each material's shader group is optimised and compiled on its own)
and the .blend's size, for 1 and 20 converted materials.

    ./scripts/dev.sh bench --only material-files [--quick]

Each case is a fresh process (``child_main``): N UV spheres, each with its own Principled BSDF
(another colour and roughness each), converted with the operator's conversion to the node
group or the OSL shader (or left Principled, OSL shading on), rendered once at 32 x 32 px and
1 sample; the sync time is Cycles' own (the EXR's metadata). The file is then saved twice,
uncompressed and compressed (Blender 5's default save compresses; 4.5's does not).
"""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))  # in a child: bench.common, addon
from bench.common import child  # noqa: E402

SECTION = "material-files"
IMPLEMENTATIONS = ("principled", "nodes", "osl")
COUNTS = (1, 20)
QUICK_COUNTS = (1, 4)


def _child_case(impl: str, n: int, out: Path) -> dict:
    import bpy

    from addon.blender import compat, convert, renderer

    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.engine = 'CYCLES'
    scene.cycles.device = 'CPU'
    scene.cycles.samples = 1
    scene.render.resolution_x = scene.render.resolution_y = 32
    scene.world = bpy.data.worlds.new("World")
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    cam.location, cam.rotation_euler = (0.0, -12.0, 0.0), (1.5708, 0.0, 0.0)
    scene.collection.objects.link(cam)
    scene.camera = cam
    for i in range(n):
        bpy.ops.mesh.primitive_uv_sphere_add(radius=0.4, location=(i % 5 - 2, 0, i // 5 - 2))
        mat = bpy.data.materials.new(f"Material {i}")
        compat.use_nodes(mat)
        bsdf = mat.node_tree.nodes["Principled BSDF"]
        bsdf.inputs["Base Color"].default_value = (0.1 + 0.04 * i, 0.5, 0.3, 1.0)
        bsdf.inputs["Roughness"].default_value = 0.2 + 0.03 * i
        bpy.context.object.data.materials.append(mat)
        if impl != "principled":
            convert.principled_to_model(mat, scene, impl)
    scene.cycles.shading_system = impl != "nodes"
    out.mkdir(parents=True, exist_ok=True)
    scene.render.filepath = str(out / "render.exr")
    scene.render.image_settings.file_format = 'OPEN_EXR'
    with renderer.quiet(os.devnull):
        bpy.ops.render.render(write_still=True)
    info = {"implementation": impl, "materials": n}
    info.update(renderer.cycles_times(out / "render.exr"))
    # the compiled shader's copies in the file: one per script node, in a material or in the
    # OSL materials' shared group (blender/osl_shader.py shared_group)
    trees = [m.node_tree for m in bpy.data.materials if m.node_tree] + list(bpy.data.node_groups)
    scripts = [n for t in trees for n in t.nodes if n.bl_idname == "ShaderNodeScript"]
    info["bytecode_bytes"] = len(scripts[0].bytecode) if scripts else 0
    info["bytecode_copies"] = len(scripts)
    for compress in (False, True):
        path = out / f"file-{int(compress)}.blend"
        bpy.ops.wm.save_as_mainfile(filepath=str(path), copy=True, compress=compress)
        info[f"blend_bytes_{'compressed' if compress else 'plain'}"] = path.stat().st_size
    return info


def child_main(args: list) -> None:
    """A child process: ``IMPLEMENTATION N OUT``; prints its RESULT line."""
    import bpy

    bpy.utils.expose_bundled_modules()
    info = _child_case(args[0], int(args[1]), Path(args[2]))
    print("RESULT " + json.dumps(info), flush=True)
    sys.stdout.flush()
    os._exit(0)  # bpy as a module can hang at exit (tests/conftest.py)


def bench_material_files(quick: bool, work: Path) -> dict:
    """Every implementation at each count, a fresh process each; the section's data."""
    runs = []
    for n in QUICK_COUNTS if quick else COUNTS:
        for impl in IMPLEMENTATIONS:
            r = child(SECTION, impl, n, work / f"files-{impl}-{n}")
            runs.append(r)
            print(f"material-files: {impl} x {n}: sync {r['sync_seconds']:.2f} s", flush=True)
    return {"runs": runs}


def material_files_table(section: dict) -> list:
    lines = [
        "N UV spheres, each with its own material converted from Principled BSDF (or left "
        "Principled, OSL shading on), rendered once at 32 px and 1 sample, a fresh process "
        "each; sync = Cycles' synchronisation (OSL: each material's shader compiled); the "
        "file saved uncompressed and compressed.",
        "",
        "| implementation | materials | sync s | OSL bytecode: copies x size | .blend MB | "
        ".blend MB, compressed |",
        "|---|---|---|---|---|---|",
    ]
    for r in section["runs"]:
        copies = r.get("bytecode_copies", r["materials"])  # before: one per material
        code = f"{copies} x {r['bytecode_bytes'] / 1e3:.0f} kB" if r["bytecode_bytes"] else "–"
        lines.append(
            f"| {r['implementation']} | {r['materials']} | **{r['sync_seconds']:.2f}** | "
            f"{code} | {r['blend_bytes_plain'] / 1e6:.2f} | "
            f"{r['blend_bytes_compressed'] / 1e6:.2f} |"
        )
    return lines
