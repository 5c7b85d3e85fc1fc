"""Blender for the render and slow tiers: bpy imported (Blender as a module), its bundled
modules exposed (addon/blender/__init__.py), and the fixtures those tiers share."""

import bpy  # noqa: F401  (Blender as a module)
import numpy as np
import pytest

from addon import blender  # noqa: F401  (exposes Blender's bundled modules)
from addon.core.hdri import write_float_exr


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
