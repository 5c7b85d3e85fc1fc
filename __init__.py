"""Cook-Torrance Lab: a Blender extension (the repository root is the extension source)."""

# Blender imports this folder as a package (bl_ext.<repo>.cook_torrance_lab). A test runner may
# import it as a plain module when the checkout's folder name is not an identifier (pytest
# sets up the root package for the tests below it): then there is nothing to register.
if __package__:
    from .addon.ui.register import register, unregister  # noqa: F401
