"""The unit tier runs without Blender: no bpy import. The core reads and writes images with
Blender's own OpenImageIO, which lies inside the bpy package (never the PyPI wheel beside it:
that breaks OSL compilation); it is put on sys.path here without starting Blender."""

import importlib.util
import sys
from pathlib import Path


def _expose_bundled_openimageio() -> None:
    spec = importlib.util.find_spec("bpy")
    if spec is None or spec.origin is None:
        return
    for site in sorted(Path(spec.origin).parent.glob("*/python/lib/python*/site-packages")):
        if (site / "OpenImageIO").is_dir():
            sys.path.append(str(site))
            return


_expose_bundled_openimageio()
