"""Blender's interface: operators, panels, properties, preferences; ui/register.py adds and
removes them all."""
