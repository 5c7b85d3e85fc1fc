"""The pure core: no bpy import (tests/unit/test_layers.py checks). OpenImageIO is Blender's own,
made importable by the Blender layer or the entry point."""
