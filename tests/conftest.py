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

import bpy  # noqa: E402

bpy.utils.expose_bundled_modules()

from addon import cli, compare  # noqa: E402
from addon.hdri import write_float_exr  # noqa: E402
from addon.params import ModelOptions  # noqa: E402
from addon.scene_builder import MatrixSettings  # noqa: E402


def render(out_dir, shader="osl", view="full", samples=16, grid=(3, 3), size=96, **kw):
    """Render the sphere matrix with the real pipeline; returns (linear image, scene dict)."""
    model_keys = ("g_model", "diffuse_model", "units", "ibl", "env_samples", "env_visibility",
                  "sun_shadow", "seed")
    model = ModelOptions(view=view, **{k: kw.pop(k) for k in model_keys if k in kw})
    s = MatrixSettings(rows=grid[0], cols=grid[1], width=size, height=size, shader=shader,
                       model=model, **kw)
    cli.render_one(s, Path(out_dir), samples, verbose=False)
    return compare.read_image(Path(out_dir) / "render.exr"), json.loads(
        (Path(out_dir) / "scene.json").read_text())


def sphere_pixels(scene, cell, margin_px=1.0):
    """Boolean mask of the pixels whose centres lie inside the sphere (minus a margin)."""
    return compare.cell_mask((scene["height"], scene["width"]),
                             cell, 1.0 - margin_px / cell["radius_px"])


@pytest.fixture(scope="session")
def uniform_hdri(tmp_path_factory):
    """A uniform white world of radiance 1 (64x32 float EXR)."""
    path = tmp_path_factory.mktemp("hdri") / "white.exr"
    write_float_exr(path, np.ones((32, 64, 3), dtype=np.float32))
    return str(path)
