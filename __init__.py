"""Cook-Torrance Lab: a Blender extension (the repository root is the extension source).

Blender imports this folder as a package (bl_ext.<repo>.cook_torrance_lab) and calls
``register`` and ``unregister``; they import the interface (addon/ui/register.py) only then, so
that importing the package starts no Blender: a test runner imports it as the root package of
the tests below it, and the unit tier (tests/unit) runs without bpy."""


def register():
    from .addon.ui.register import register as register_addon

    register_addon()


def unregister():
    from .addon.ui.register import unregister as unregister_addon

    unregister_addon()
