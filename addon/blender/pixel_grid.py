"""A render in which each pixel is one evaluation of a material: a plane that fills an
orthographic camera's frame exactly, W x H pixels, whose material reads per-pixel data
(directions, random numbers) from float images at the pixel's centre.

Rendered with one sample at each pixel centre (renderer.configure with ``pixel_centres``),
pixel (i, j), row j counted from the top, evaluates the material with ``data[j, i]`` of every
data image. The camera looks along -Z, so the direction toward the viewer (OSL's ``I``,
Geometry's Incoming) is +Z at every pixel. The BRDF plots (blender/model_eval.py) and the
sampling tests use it.
"""

from __future__ import annotations

import bpy
import numpy as np

from . import owned, renderer

TAG = "ctlab_pixel_grid"
CAMERA_HEIGHT = 10.0


def build(scene: bpy.types.Scene, width: int, height: int) -> bpy.types.Object:
    """The plane (W x H units, one per pixel, UV 0..1 over it) and the camera framing it
    exactly, in ``scene``; returns the plane, whose material the caller gives."""
    mesh = bpy.data.meshes.new("Cook-Torrance Lab Pixel Grid")
    mesh.from_pydata(
        [(0, 0, 0), (width, 0, 0), (width, height, 0), (0, height, 0)], [], [(0, 1, 2, 3)]
    )
    uv = mesh.uv_layers.new(name="UVMap")
    for loop, coords in zip(mesh.loops, ((0, 0), (1, 0), (1, 1), (0, 1))):
        uv.data[loop.index].uv = coords
    plane = bpy.data.objects.new("Cook-Torrance Lab Pixel Grid", mesh)
    plane[TAG] = True
    scene.collection.objects.link(plane)

    cam_data = bpy.data.cameras.new("Cook-Torrance Lab Pixel Grid Camera")
    cam_data.type = 'ORTHO'
    cam_data.sensor_fit = 'AUTO'  # ortho_scale spans the longer side
    cam_data.ortho_scale = max(width, height)
    cam_data.clip_start, cam_data.clip_end = 0.1, 2 * CAMERA_HEIGHT
    cam = bpy.data.objects.new("Cook-Torrance Lab Pixel Grid Camera", cam_data)
    cam[TAG] = True
    cam.location = (width / 2, height / 2, CAMERA_HEIGHT)  # no rotation: looks along -Z
    scene.collection.objects.link(cam)
    scene.camera = cam
    scene.world = None
    scene.render.resolution_x, scene.render.resolution_y = width, height
    scene.render.resolution_percentage = 100
    scene.render.pixel_aspect_x = scene.render.pixel_aspect_y = 1.0
    return plane


def data_image(name: str, data: np.ndarray) -> bpy.types.Image:
    """A float image holding ``data`` (H, W, 3 or 4; row 0 the top, as the render's), read
    without colour conversion. An earlier data image of ours of that name is replaced, a
    user's image of that name never (blender/owned.py: ours is then "<name>.001")."""
    data = np.asarray(data, dtype=np.float32)
    h, w = data.shape[:2]
    rgba = np.ones((h, w, 4), dtype=np.float32)
    rgba[..., : data.shape[2]] = data
    old = owned.find(bpy.data.images, name, owned.DATA_IMAGE)
    if old is not None:
        bpy.data.images.remove(old)
    image = owned.new(bpy.data.images, name, owned.DATA_IMAGE, w, h, alpha=True, float_buffer=True)
    image.colorspace_settings.name = "Non-Color"
    image.alpha_mode = 'NONE'
    image.pixels.foreach_set(np.ascontiguousarray(rgba[::-1]).ravel())  # Blender: bottom row first
    image.pack()  # a generated image: kept with the file
    return image


def image_input(tree: bpy.types.NodeTree, image: bpy.types.Image) -> bpy.types.NodeSocket:
    """An Image Texture node reading ``image`` at the pixel's own texel (Closest, at the
    plane's UV); its Color output."""
    node = tree.nodes.new("ShaderNodeTexImage")
    node.image = image
    node.interpolation = 'Closest'
    node.extension = 'EXTEND'
    return node.outputs["Color"]


def render(scene: bpy.types.Scene, log_path=None) -> np.ndarray:
    """Render the scene's camera (configured by the caller) and return the float RGB image
    (H, W, 3), row 0 the top. The image passes through a private temporary folder, removed
    after."""
    from ..core.compare import read_image
    from ..core.files import temporary_folder

    result = renderer.render_result(log_path)
    with temporary_folder("ctlab-pixels-") as folder:  # removed on a signal too
        path = folder / "pixels.exr"
        with renderer.quiet(log_path):
            renderer.save_exr(scene, result, path)
        return read_image(path)
