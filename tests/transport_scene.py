"""A scene where path tracing matters, for the scene transport's render tests
(tests/slow/test_scene_transport_nodes.py): a metal and a dielectric sphere beside a red cube
on a grey floor under Blender's forest HDRI (``Scene``), and the materials they are rendered
with: the node group (``group_material``), a Principled BSDF metal (``principled_metal``) and
an OSL script of generalized_schlick_bsdf + diffuse built by hand from docs/model.md's
formulas (``osl_reference``); ``scene_renders`` renders them all."""

import math
import tempfile

import numpy as np

from addon.blender import compat

SIZE, SAMPLES = 64, 64
# (albedo, metallic, smoothness): a copper-like metal and a blue dielectric
SPHERES = (
    dict(albedo=(0.95, 0.64, 0.54), metallic=1.0, smoothness=0.6),
    dict(albedo=(0.2, 0.35, 0.8), metallic=0.0, smoothness=0.45),
)
LOCATIONS = ((-0.65, 0.0, 0.5), (0.75, -0.2, 0.5))
CUBE = (0.1, 0.75, 0.4)

# generalized_schlick_bsdf(f0, f90 = 1, exponent 5, GGX, roughness arguments = alpha) is GGX
# with Schlick's F and the height-correlated Smith G (Cycles' OSL closures); diffuse() Lambert.
OSL_REFERENCE = """
shader reference(color f0 = 0.04, color diffColor = 0, float alpha = 0.25,
                 output closure color BSDF = 0)
{
    BSDF = generalized_schlick_bsdf(N, vector(0), color(1), color(0), alpha, alpha, f0,
                                    color(1), 5.0, "ggx") + diffColor * diffuse(N);
}
"""


def _one_node_material(name, idname, colour):
    """A material whose surface is one node of ``idname`` (its Color input ``colour``)."""
    import bpy

    mat = bpy.data.materials.new(name)
    compat.use_nodes(mat)
    nt = mat.node_tree
    nt.nodes.clear()
    node = nt.nodes.new(idname)
    node.inputs["Color"].default_value = tuple(colour) + (1.0,)
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    nt.links.new(node.outputs[0], out.inputs["Surface"])
    return mat


def diffuse_material(name, colour):
    return _one_node_material(name, "ShaderNodeBsdfDiffuse", colour)


def emission_material(name, colour):
    return _one_node_material(name, "ShaderNodeEmission", colour)


class Scene:
    """Two spheres (radius 0.5), a red cube behind them and a grey floor (Diffuse BSDFs), a
    perspective camera, in an empty file, under forest.exr (its sun near 1437). Built once;
    each render sets the spheres' (and the cube's) materials."""

    def __init__(self):
        import bpy
        from addon.blender.paths import bundled_hdri

        bpy.ops.wm.read_factory_settings(use_empty=True)
        scene = self.scene = bpy.context.scene
        w = self.world = bpy.data.worlds.new("forest")
        compat.use_nodes(w)
        nt = w.node_tree
        nt.nodes.clear()
        env = nt.nodes.new("ShaderNodeTexEnvironment")
        env.image = bpy.data.images.load(str(bundled_hdri("forest")))
        bg = nt.nodes.new("ShaderNodeBackground")
        out = nt.nodes.new("ShaderNodeOutputWorld")
        nt.links.new(env.outputs["Color"], bg.inputs["Color"])
        nt.links.new(bg.outputs["Background"], out.inputs["Surface"])
        self.grey = diffuse_material("grey", (0.5, 0.5, 0.5))
        self.red = diffuse_material("red", (0.8, 0.05, 0.05))
        bpy.ops.mesh.primitive_plane_add(size=20)
        self.floor = bpy.context.active_object
        bpy.ops.mesh.primitive_cube_add(size=0.8, location=CUBE)
        self.cube = bpy.context.active_object
        self.spheres = []
        for location in LOCATIONS:
            bpy.ops.mesh.primitive_uv_sphere_add(
                segments=48, ring_count=24, radius=0.5, location=location
            )
            bpy.ops.object.shade_smooth()
            self.spheres.append(bpy.context.active_object)
        cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
        cam.location = (0.0, -4.0, 1.6)
        cam.rotation_euler = (math.radians(72), 0.0, 0.0)
        scene.collection.objects.link(cam)
        scene.camera = cam
        scene.render.resolution_x = scene.render.resolution_y = SIZE
        scene.render.resolution_percentage = 100

    @staticmethod
    def _set(obj, mat):
        obj.data.materials.clear()
        obj.data.materials.append(mat)

    def render(
        self,
        tmp,
        name,
        spheres,
        floor=None,
        cube=None,
        shader="nodes",
        seed=0,
        world=True,
        samples=SAMPLES,
        pixel_centres=False,
    ):
        """The linear image (float64, rows top-down as read_image gives them)."""
        from addon.blender import renderer
        from addon.core.compare import read_image

        for obj, mat in zip(self.spheres, spheres):
            self._set(obj, mat)
        self._set(self.floor, floor or self.grey)
        self._set(self.cube, cube or self.red)
        self.scene.world = self.world if world else None
        renderer.configure(
            self.scene,
            shader,
            "full",
            samples,
            seed=seed,
            path_traced=True,
            pixel_centres=pixel_centres,
        )
        image = renderer.render_result(tmp / "log.txt")
        path = tmp / f"{name}.exr"
        renderer.save_exr(self.scene, image, path)
        return read_image(path).astype(np.float64)

    def masks(self, tmp):
        """The pixels whose centre sees sphere 0 or 1 (an emission render, one sample at each
        pixel centre, no world)."""
        black = emission_material("id black", (0, 0, 0))
        image = self.render(
            tmp,
            "masks",
            (emission_material("id 0", (1, 0, 0)), emission_material("id 1", (0, 1, 0))),
            floor=black,
            cube=black,
            world=False,
            samples=1,
            pixel_centres=True,
        )
        return [image[..., 0] > 0.5, image[..., 1] > 0.5]


def group_material(surface, name):
    """The node group (through the project's material builder) in the scene transport with the
    exact switches: height-correlated Smith G, Lambert, no energy compensation."""
    from addon.blender import materials
    from addon.core.model import ModelOptions

    options = ModelOptions(
        g_model="smith_ggx_correlated",
        diffuse_model="lambert",
        energy="none",
        light_transport="scene",
        ibl="split_sum",
    )
    return materials.model_material(name, impl="nodes", options=options, **surface)


def principled_metal(surface, name):
    """Principled BSDF, metallic 1: F82-tint Fresnel with its default white specular tint, i.e.
    Schlick's on Base Color; GGX with alpha = Roughness^2 = (1 - smoothness)^2."""
    import bpy

    assert surface["metallic"] == 1.0
    mat = bpy.data.materials.new(name)
    compat.use_nodes(mat)
    nt = mat.node_tree
    nt.nodes.clear()
    bsdf = nt.nodes.new("ShaderNodeBsdfPrincipled")
    bsdf.distribution = 'GGX'
    bsdf.inputs["Base Color"].default_value = tuple(surface["albedo"]) + (1.0,)
    bsdf.inputs["Metallic"].default_value = 1.0
    bsdf.inputs["Roughness"].default_value = 1.0 - surface["smoothness"]
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    nt.links.new(bsdf.outputs["BSDF"], out.inputs["Surface"])
    return mat


def osl_reference(surface, name):
    """The OSL script above with the model's inputs: specColor, diffColor, alpha."""
    import bpy
    import cycles.osl

    mat = bpy.data.materials.new(name)
    compat.use_nodes(mat)
    nt = mat.node_tree
    nt.nodes.clear()
    text = bpy.data.texts.get("reference.osl") or bpy.data.texts.new("reference.osl")
    text.from_string(OSL_REFERENCE)
    node = nt.nodes.new("ShaderNodeScript")
    node.mode = 'INTERNAL'
    errors = []
    saved = tempfile.tempdir
    with tempfile.TemporaryDirectory() as private:  # where Cycles leaves its .oso
        tempfile.tempdir = private
        try:
            node.script = text
            cycles.osl.update_script_node(
                node, lambda kind, msg: errors.append(msg) if 'ERROR' in kind else None
            )
        finally:
            tempfile.tempdir = saved
    assert not errors and "f0" in node.inputs, errors
    albedo, m = np.array(surface["albedo"]), surface["metallic"]
    pr = 1.0 - surface["smoothness"]
    node.inputs["f0"].default_value = tuple(0.04 * (1 - m) + albedo * m) + (1.0,)
    node.inputs["diffColor"].default_value = tuple(albedo * 0.96 * (1 - m)) + (1.0,)
    node.inputs["alpha"].default_value = max(pr * pr, 0.002)
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    nt.links.new(node.outputs["BSDF"], out.inputs["Surface"])
    return mat


def scene_renders(tmp, scene=None):
    """The renders the tests compare (64 x 64, 64 samples, seed 0, 12 bounces)."""
    scene = scene or Scene()
    group = tuple(group_material(s, f"group {k}") for k, s in enumerate(SPHERES))
    return scene, {
        "group": scene.render(tmp, "group", group),
        "principled": scene.render(
            tmp, "principled", (principled_metal(SPHERES[0], "principled metal"), group[1])
        ),
        "osl": scene.render(
            tmp,
            "osl",
            tuple(osl_reference(s, f"osl {k}") for k, s in enumerate(SPHERES)),
            shader="osl",
        ),
        # the group with a grey cube in place of the red one
        "grey cube": scene.render(tmp, "grey cube", group, cube=scene.grey),
    }
