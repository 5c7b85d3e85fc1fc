"""What the tests share besides fixtures: the repository's root, a render of the sphere matrix
through the real pipeline, a Sun-lit sphere rendered in this process, the sphere mask of a
cell, bad HDRIs, and what the bad-input tests
share (the command as a process, one error line, a folder's listing, a tiny HDRI, Hypothesis'
settings). Importing this module starts no Blender; ``render`` does."""

import json
import sys
from pathlib import Path

import numpy as np
from hypothesis import HealthCheck, settings

ROOT = Path(__file__).resolve().parent.parent
CTLAB = [sys.executable, str(ROOT / "scripts" / "ctlab.py")]  # the command, as a process
TINY = ["--grid", "1x1", "--size", "32", "--samples", "1"]
# Hypothesis for the bad-input properties: many cheap examples, the same ones every run
FAST = settings(
    max_examples=300,
    deadline=None,
    derandomize=True,
    database=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture],
)


def render(
    out_dir,
    shader="osl",
    view="full",
    samples=16,
    grid=(3, 3),
    size=96,
    pixel_centres=False,
    engine="cycles",
    **kw,
):
    """Render the sphere matrix with the real pipeline; returns (linear image, scene dict).
    With a tuple of views: ({view: image}, scene), the scene built and compiled once."""
    from addon.core import compare
    from addon.core.model import ModelOptions
    from addon.core.settings import MatrixSettings
    from addon.jobs import pipeline

    model_keys = (
        "g_model",
        "diffuse_model",
        "units",
        "energy",
        "ibl",
        "env_samples",
        "env_visibility",
        "sun_shadow",
        "seed",
        "light_transport",
    )
    views = view if isinstance(view, tuple) else (view,)
    model = ModelOptions(view=views[0], **{k: kw.pop(k) for k in model_keys if k in kw})
    s = MatrixSettings(
        rows=grid[0], cols=grid[1], width=size, height=size, shader=shader, model=model, **kw
    )
    dirs = (
        {v: Path(out_dir) / v for v in views} if isinstance(view, tuple) else {view: Path(out_dir)}
    )
    pipeline.render_views(s, dirs, samples, pixel_centres=pixel_centres, engine=engine)
    images = {v: compare.read_image(d / "render.exr") for v, d in dirs.items()}
    scene = json.loads((next(iter(dirs.values())) / "scene.json").read_text())
    return (images if isinstance(view, tuple) else images[view]), scene


# The key Sun of sun_lit_sphere's renders (core.model Lighting's fields)
SUN_LIT = dict(sun_to_light=(0.3, 0.4, 0.87), sun_irradiance=(2.0, 2.0, 2.0))


def sun_lit_sphere(size: int):
    """An empty scene in this process with one smooth UV sphere (64 x 32) before a camera,
    set to render the model's full view under OSL at pixel centres, ``size`` px square: the
    scene and the sphere (its material is the caller's; light it with SUN_LIT)."""
    import bpy

    from addon.blender import renderer

    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    bpy.ops.mesh.primitive_uv_sphere_add(radius=1.0, segments=64, ring_count=32)
    bpy.ops.object.shade_smooth()
    camera = bpy.data.objects.new("camera", bpy.data.cameras.new("camera"))
    scene.collection.objects.link(camera)
    camera.location = (0.0, 0.0, 4.0)
    scene.camera = camera
    renderer.configure(scene, "osl", "full", 1, pixel_centres=True)
    scene.render.resolution_x = scene.render.resolution_y = size
    scene.render.image_settings.file_format = 'OPEN_EXR'
    return scene, bpy.context.object


def render_still(scene, path: Path) -> np.ndarray:
    """Render the scene into ``path`` (its file format) and return the pixels, flat."""
    import bpy

    scene.render.filepath = str(path)
    bpy.ops.render.render(write_still=True)
    return np.array(bpy.data.images.load(str(path)).pixels[:])


def sphere_pixels(scene, cell, margin_px=1.0):
    """Boolean mask of the pixels whose centres lie inside the sphere (minus a margin)."""
    from addon.core import compare

    return compare.cell_mask(
        (scene["height"], scene["width"]), cell, 1.0 - margin_px / cell["radius_px"]
    )


def bad_images(tmp_path):
    """Bad HDRIs, keyed by the words their error message must contain."""
    from addon.core.hdri import oiio, write_float_exr

    OIIO = oiio()
    png = tmp_path / "ldr.png"
    buf = OIIO.ImageBuf(OIIO.ImageSpec(64, 32, 3, OIIO.UINT8))
    buf.write(str(png))
    mono = tmp_path / "mono.exr"
    write_float_exr(mono, np.ones((32, 64, 1), dtype=np.float32))
    square = tmp_path / "square.exr"
    write_float_exr(square, np.ones((32, 32, 3), dtype=np.float32))
    good = tmp_path / "good.exr"
    write_float_exr(
        good, np.ones((256, 512, 3), dtype=np.float32) * np.linspace(0, 1, 512)[None, :, None]
    )
    corrupt = tmp_path / "corrupt.exr"
    corrupt.write_bytes(good.read_bytes()[: good.stat().st_size // 2])
    garbage = tmp_path / "garbage.exr"
    garbage.write_bytes(b"not an image at all" * 100)
    return {
        "not floating point": png,
        "1 channel": mono,
        "not 2:1": square,
        "corrupt or truncated": corrupt,
        "HDRI unreadable": garbage,
        "HDRI not found": tmp_path / "missing.exr",
    }


def fake_render(folder, variant="good", size=32):
    """A render folder as `ctlab render` writes one (render.exr, render.png, scene.json), made
    directly, or damaged as ``variant`` says."""
    import json
    import numpy as np
    from addon.core.compare import write_png
    from addon.core.hdri import write_float_exr

    folder.mkdir(parents=True)
    img = np.full((size, size, 3), 0.5, np.float32)
    if variant == "nan":
        img[3, 4, 1] = np.nan
    write_float_exr(folder / "render.exr", img if variant != "wrongsize" else img[:, :16])
    write_png(folder / "render.png", np.clip(np.nan_to_num(img), 0, 1))
    if variant == "truncated":
        data = (folder / "render.exr").read_bytes()
        (folder / "render.exr").write_bytes(data[: len(data) // 2])
    scene = {
        "width": size,
        "height": size,
        "cells": [
            {
                "row": 0,
                "col": 0,
                "metallic": 0.0,
                "smoothness": 1.0,
                "center_px": [16, 16],
                "radius_px": 10.0,
            }
        ],
    }
    text = {"badjson": "{not json", "schema": "{}"}.get(variant, json.dumps(scene))
    (folder / "scene.json").write_text(text)
    return folder


def one_line(capsys, code, expect=None):
    """The command failed as bad input: exit 2, exactly one error line, no traceback."""
    from addon.jobs import cli

    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if line.strip()]
    assert code == cli.EXIT_BAD_INPUT, err
    assert len(lines) == 1 and lines[0].startswith("ctlab: error: "), err
    if expect:
        assert expect in lines[0], lines[0]
    return lines[0]


def listing(root: Path) -> set:
    """Every path under ``root``."""
    return set(root.rglob("*"))


def tiny_hdri(path: Path, nan=False) -> Path:
    """A 32x16 HDRI of ones (one NaN where ``nan``)."""
    from addon.core.hdri import write_float_exr

    px = np.ones((16, 32, 3), np.float32)
    if nan:
        px[2, 3, 1] = np.nan
    write_float_exr(path, px)
    return path
