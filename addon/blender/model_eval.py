"""The model evaluated at given configurations, by the model's own code: a pixel grid
(pixel_grid.py) whose material is the model node (either implementation) with its Normal and
Sun Direction read per pixel from float images, so that each pixel shades one (n, v, l) with
v = +Z, the camera's direction. A term view's pixel is then the term at that configuration
(docs/model.md "BRDF plots"). The BRDF plots use it (jobs/plot_job.py run_plot).
"""

from __future__ import annotations

import os

import bpy
import numpy as np

from . import materials, model_node, pixel_grid, renderer
from ..core import ibl_bake
from ..core.hdri import uniform_world
from ..core.model import Lighting, ModelOptions

MATERIAL = "Cook-Torrance Lab Evaluation"


class Evaluator:
    """The model node of implementation ``shader`` with constant surface values, on a pixel
    grid whose pixel (i, j) has normal ``n[j, i]`` and direction toward the light
    ``l[j, i]`` (both in the view frame: v = +Z). Builds into the current (empty) scene."""

    def __init__(
        self,
        shader: str,
        n: np.ndarray,
        l: np.ndarray,
        albedo,
        metallic: float,
        smoothness: float,
        options: ModelOptions,
        verbose: bool = False,
    ):
        self.shader = shader
        self.log = None if verbose else os.devnull
        scene = bpy.context.scene
        h, w = n.shape[:2]
        plane = pixel_grid.build(scene, w, h)
        # the node group reads the multiple-scattering tables from a bake folder: a
        # uniform world's (cached); the OSL shader reads them from the tables folder
        bake = str(ibl_bake.bake(uniform_world((1.0, 1.0, 1.0)))) if shader == "nodes" else ""
        mat = materials.model_material(
            MATERIAL,
            shader,
            options,
            Lighting(ibl_bake=bake),
            albedo=tuple(albedo),
            metallic=metallic,
            smoothness=smoothness,
        )
        tree = mat.node_tree
        self.node = model_node.find(mat)
        tree.links.new(
            pixel_grid.image_input(tree, pixel_grid.data_image("ctlab_n", n)),
            model_node.surface_input(self.node, "normal"),
        )
        tree.links.new(
            pixel_grid.image_input(tree, pixel_grid.data_image("ctlab_l", l)),
            model_node.lighting_input(self.node, "sun_to_light"),
        )
        plane.data.materials.append(mat)
        self.scene = scene

    def render(self, options: ModelOptions) -> np.ndarray:
        """The view of ``options`` at every configuration: (H, W, 3) float32."""
        model_node.set_options(self.node, options)
        renderer.configure(self.scene, self.shader, options.view, 1, pixel_centres=True)
        return pixel_grid.render(self.scene, self.log)
