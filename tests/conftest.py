"""Shared set-up: real Blender (bpy 4.5 as a module), a private cache, small renders."""

import json
import os
import sys
import tempfile
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
_CACHE = tempfile.mkdtemp(prefix="ctlab-test-cache-")
os.environ.setdefault("CTLAB_CACHE", _CACHE)
os.environ.setdefault("XDG_CACHE_HOME", _CACHE)

import bpy  # noqa: E402,F401  (Blender as a module)

from addon import blender  # noqa: E402,F401  (exposes Blender's bundled modules)
from addon.core import compare  # noqa: E402
from addon.core.hdri import write_float_exr  # noqa: E402
from addon.core.model import ModelOptions  # noqa: E402
from addon.core.settings import MatrixSettings  # noqa: E402
from addon.jobs import pipeline  # noqa: E402


def pytest_configure(config):
    config.addinivalue_line("markers", "quick: the fast tier (no renders); "
                                       "./scripts/test.sh --quick runs only these")


def render(out_dir, shader="osl", view="full", samples=16, grid=(3, 3), size=96,
           pixel_centres=False, engine="cycles", **kw):
    """Render the sphere matrix with the real pipeline; returns (linear image, scene dict).
    With a tuple of views: ({view: image}, scene), the scene built and compiled once."""
    model_keys = ("g_model", "diffuse_model", "units", "energy", "ibl", "env_samples",
                  "env_visibility", "sun_shadow", "seed", "light_transport")
    views = view if isinstance(view, tuple) else (view,)
    model = ModelOptions(view=views[0], **{k: kw.pop(k) for k in model_keys if k in kw})
    s = MatrixSettings(rows=grid[0], cols=grid[1], width=size, height=size, shader=shader,
                       model=model, **kw)
    dirs = {v: Path(out_dir) / v for v in views} if isinstance(view, tuple) else \
        {view: Path(out_dir)}
    pipeline.render_views(s, dirs, samples, pixel_centres=pixel_centres, engine=engine)
    images = {v: compare.read_image(d / "render.exr") for v, d in dirs.items()}
    scene = json.loads((next(iter(dirs.values())) / "scene.json").read_text())
    return (images if isinstance(view, tuple) else images[view]), scene


def sphere_pixels(scene, cell, margin_px=1.0):
    """Boolean mask of the pixels whose centres lie inside the sphere (minus a margin)."""
    return compare.cell_mask((scene["height"], scene["width"]),
                             cell, 1.0 - margin_px / cell["radius_px"])


@pytest.fixture
def addon():
    """The add-on registered in a factory-startup scene (the default cube, light, camera)."""
    from addon.ui import register
    bpy.ops.wm.read_factory_settings(use_empty=False)
    register.register()
    yield
    register.unregister()


@pytest.fixture(scope="session")
def uniform_hdri(tmp_path_factory):
    """A uniform white world of radiance 1 (64x32 float EXR)."""
    path = tmp_path_factory.mktemp("hdri") / "white.exr"
    write_float_exr(path, np.ones((32, 64, 3), dtype=np.float32))
    return str(path)


def bad_images(tmp_path):
    """Bad HDRIs, keyed by the words their error message must contain."""
    from addon.core.hdri import oiio
    OIIO = oiio()
    png = tmp_path / "ldr.png"
    buf = OIIO.ImageBuf(OIIO.ImageSpec(64, 32, 3, OIIO.UINT8))
    buf.write(str(png))
    mono = tmp_path / "mono.exr"
    write_float_exr(mono, np.ones((32, 64, 1), dtype=np.float32))
    square = tmp_path / "square.exr"
    write_float_exr(square, np.ones((32, 32, 3), dtype=np.float32))
    good = tmp_path / "good.exr"
    write_float_exr(good, np.ones((256, 512, 3), dtype=np.float32) * np.linspace(0, 1, 512)[None, :, None])
    corrupt = tmp_path / "corrupt.exr"
    corrupt.write_bytes(good.read_bytes()[: good.stat().st_size // 2])
    garbage = tmp_path / "garbage.exr"
    garbage.write_bytes(b"not an image at all" * 100)
    return {"not floating point": png, "1 channel": mono, "not 2:1": square,
            "corrupt or truncated": corrupt, "HDRI unreadable": garbage,
            "HDRI not found": tmp_path / "missing.exr"}
