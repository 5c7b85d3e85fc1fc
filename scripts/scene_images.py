"""The docs' images of the scene light transport (docs/scene_transport.png and
docs/scene_transport_sky.png): the demo scene (addon/blender/demo_scene.py) rendered with
the metal sphere as the Cook-Torrance OSL shader in the scene transport (Smith G, Lambert),
as Principled BSDF (GGX), and as the same material in the lab transport, side by side, with
the mean CIEDE2000 over the sphere printed.

    ./scripts/dev.sh scene_images [--samples 256] [--size 320x240]
"""

import argparse
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
import bpy  # noqa: E402,F401  (Blender as a module)
import numpy as np  # noqa: E402

import addon.blender  # noqa: E402,F401  (exposes Blender's bundled OpenImageIO)
from addon.blender import demo_scene, light_sync, materials, model_node, renderer  # noqa: E402
from addon.core import compare  # noqa: E402
from addon.core.model import ModelOptions  # noqa: E402


def render(scene, out: Path, shader: str, samples: int):
    renderer.configure(scene, shader, "full", samples, path_traced=True)
    renderer.render(
        scene, out, {"width": scene.render.resolution_x, "height": scene.render.resolution_y}
    )
    return compare.read_image(out / "render.exr"), compare.read_image(out / "render.png")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--samples", type=int, default=256)
    ap.add_argument("--size", default="320x240")
    args = ap.parse_args()
    w, h = (int(x) for x in args.size.split("x"))
    for world, name in (("hdri", "scene_transport.png"), ("sky", "scene_transport_sky.png")):
        scene, sphere, other = demo_scene.build(world, w, h)
        demo_scene.set_material(other, demo_scene.principled_for(demo_scene.ORANGE, "Orange"))
        with tempfile.TemporaryDirectory() as tmp:
            tmp = Path(tmp)
            demo_scene.set_material(sphere, demo_scene.principled_for(demo_scene.METAL))
            _, ref = render(scene, tmp / "principled", "principled", args.samples)
            mat = materials.model_material(
                "Cook-Torrance",
                "osl",
                ModelOptions(
                    light_transport="scene", g_model="smith_ggx_correlated", diffuse_model="lambert"
                ),
                **demo_scene.METAL,
            )
            demo_scene.set_material(sphere, mat)
            light_sync.sync_material(mat, scene)
            _, path = render(scene, tmp / "scene", "osl", args.samples)
            model_node.set_option(model_node.find(mat), "light_transport", "lab")
            _, lab = render(scene, tmp / "lab", "osl", args.samples)
        mask = demo_scene.sphere_mask(scene, sphere, ref.shape[:2])
        for label, img in (("scene", path), ("lab", lab)):
            de = compare.ciede2000(compare.srgb_to_lab(ref), compare.srgb_to_lab(img))
            print(
                f"{world}: {label} vs Principled, mean CIEDE2000 over the sphere "
                f"{de[mask].mean():.2f}"
            )
        gap = np.ones((h, 4, 3), dtype=np.float32)
        compare.write_png(ROOT / "docs" / name, np.concatenate([path, gap, ref, gap, lab], 1))
        print(f"wrote docs/{name}")


if __name__ == "__main__":
    main()
