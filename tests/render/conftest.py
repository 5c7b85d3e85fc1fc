"""This tier runs in real Blender: tests/blender_fixtures.py imports bpy and gives the fixtures."""

from blender_fixtures import addon, uniform_hdri  # noqa: F401  (fixtures)
