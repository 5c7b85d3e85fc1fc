"""The node group's scene transport: with Light Transport Scene = 1 and the full view, the
group's Emission output is Cycles closures (a Metallic BSDF, F82 with a white edge tint, GGX,
plus a Lambert Diffuse BSDF) that Cycles path traces, not the lab's emission.

- The structure (quick): the closures are fed as the model says, and the switch between them
  and the lab's emission is exactly (Light Transport Scene == 1) x (View == full), evaluated
  over the group's Math and Vector Math nodes by a small interpreter of their operations.
- A render where path tracing matters (a metal and a dielectric sphere beside a red cube on a
  grey floor, under Blender's forest HDRI): the group against two materials built by hand
  from the model's formulas, a Principled BSDF (metallic 1, GGX) for the metal sphere and an
  OSL script of generalized_schlick_bsdf + diffuse for both spheres.
"""

import math

import numpy as np
import pytest

from addon.blender import compat
from addon.core.model import VIEWS

FULL = VIEWS.index("full")


# --- Structure ------------------------------------------------------------------------------

_MATH = {
    "ADD": lambda a, b: a + b, "SUBTRACT": lambda a, b: a - b,
    "MULTIPLY": lambda a, b: a * b, "DIVIDE": lambda a, b: a / b if b else 0.0,
    "MAXIMUM": max, "MINIMUM": min, "SQRT": lambda a, b: math.sqrt(a) if a > 0 else 0.0,
    "GREATER_THAN": lambda a, b: float(a > b), "LESS_THAN": lambda a, b: float(a < b),
}
_VEC = {"ADD": np.add, "SUBTRACT": np.subtract, "MULTIPLY": np.multiply,
        "MINIMUM": np.minimum, "MAXIMUM": np.maximum}


def _input_value(sock, inputs):
    if sock.is_linked:
        return _evaluate(sock.links[0].from_socket, inputs)
    v = sock.default_value
    return np.array(v[:3], dtype=np.float64) if hasattr(v, "__len__") else float(v)


def _evaluate(sock, inputs):
    """The value of an output socket built from the group's inputs by Math and Vector Math
    nodes, per Blender's documented operations (``inputs``: group input name -> value)."""
    node = sock.node
    if node.bl_idname == "NodeGroupInput":
        return inputs[sock.name]
    if node.bl_idname == "ShaderNodeMath":
        a, b, c = (_input_value(s, inputs) for s in node.inputs[:3])
        if node.operation == "COMPARE":
            out = float(abs(a - b) <= max(c, 1e-5))
        else:
            out = _MATH[node.operation](a, b)
        return min(max(out, 0.0), 1.0) if node.use_clamp else out
    if node.bl_idname == "ShaderNodeVectorMath":
        a = _input_value(node.inputs[0], inputs)
        if node.operation == "SCALE":
            return a * _input_value(node.inputs["Scale"], inputs)
        return _VEC[node.operation](a, _input_value(node.inputs[1], inputs))
    raise AssertionError(f"cannot evaluate {node.bl_idname} {node.name} ({node.label})")


def _source(sock):
    assert sock.is_linked, f"{sock.node.name}.{sock.name} is not linked"
    return sock.links[0].from_socket


def _group_inputs(**values):
    from addon.core.model import GROUP_INPUTS
    out = {}
    for i in GROUP_INPUTS:
        v = values.get(i.group, i.default)
        out[i.group] = np.array(v[:3], dtype=np.float64) if isinstance(v, tuple) else float(v)
    return out


@pytest.fixture(scope="module")
def group():
    import bpy
    from addon.blender import node_group
    name = "ctlab scene transport test"
    yield node_group.build_group(name)
    for key in (name + " Light", name):          # unless a later reset removed them
        if key in bpy.data.node_groups:
            bpy.data.node_groups.remove(bpy.data.node_groups[key])


@pytest.mark.quick
def test_the_emission_is_the_closures_exactly_for_the_scene_transports_full_view(group):
    out = next(n for n in group.nodes if n.bl_idname == "NodeGroupOutput")
    select = _source(out.inputs["Emission"]).node
    assert select.bl_idname == "ShaderNodeMixShader"
    lab, scene = (_source(select.inputs[k]).node for k in (1, 2))
    for transport in (0, 1):
        for view in range(len(VIEWS)):
            fac = _evaluate(_source(select.inputs["Fac"]), _group_inputs(**{
                "Light Transport Scene": transport, "View": view}))
            assert fac == float(transport == 1 and view == FULL), (transport, VIEWS[view])

    def upstream(node, found):
        found.append(node)
        for s in node.inputs:
            if s.is_linked and s.type == 'SHADER':
                upstream(s.links[0].from_node, found)
        return found
    bsdfs = ("ShaderNodeBsdfMetallic", "ShaderNodeBsdfDiffuse")
    assert not [n for n in upstream(lab, []) if n.bl_idname in bsdfs]   # the lab only emits
    scene_nodes = upstream(scene, [])
    assert not [n for n in scene_nodes if n.bl_idname == "ShaderNodeEmission"]
    metals = [n for n in scene_nodes if n.bl_idname == "ShaderNodeBsdfMetallic"]
    diffuse = [n for n in scene_nodes if n.bl_idname == "ShaderNodeBsdfDiffuse"]
    assert len(metals) == 2 and len(diffuse) == 1
    # GGX, or Multiscatter GGX exactly where Energy Compensated is 1, by a 0-or-1 Mix Shader
    chooser = next(n for n in scene_nodes if n.bl_idname == "ShaderNodeMixShader"
                   and {_source(n.inputs[k]).node for k in (1, 2)} == set(metals))
    for energy in (0, 1):
        fac = _evaluate(_source(chooser.inputs["Fac"]),
                        _group_inputs(**{"Energy Compensated": energy}))
        assert fac == energy
    assert _source(chooser.inputs[1]).node.distribution == 'GGX'
    assert _source(chooser.inputs[2]).node.distribution == 'MULTI_GGX'

    diffuse = diffuse[0]
    for metal in metals:
        assert metal.fresnel_type == 'F82'
        assert tuple(metal.inputs["Edge Tint"].default_value) == (1, 1, 1, 1)
        assert not metal.inputs["Edge Tint"].is_linked
        assert not metal.inputs["Anisotropy"].is_linked
        assert metal.inputs["Anisotropy"].default_value == 0
        if "Thin Film Thickness" in metal.inputs:            # 5.x
            assert metal.inputs["Thin Film Thickness"].default_value == 0
        # the shading normal the lab uses (the group's n: Normal input or geometry's)
        assert _source(metal.inputs["Normal"]).node.label == "n"
    assert _source(diffuse.inputs["Normal"]).node.label == "n"
    assert not diffuse.inputs["Roughness"].is_linked
    assert diffuse.inputs["Roughness"].default_value == 0          # Lambert

    # the colours and the roughness, from the model's formulas (UnityStandardUtils):
    # specColor = lerp(0.04, albedo, m), diffColor = albedo 0.96 (1 - m), and the node squares
    # its Roughness: Roughness = sqrt(alpha) = max(1 - smoothness, sqrt(0.002))
    for albedo, m, s in (((0.9, 0.5, 0.2), 0.0, 0.5), ((0.3, 0.7, 1.0), 1.0, 0.9),
                         ((0.5, 0.25, 0.125), 0.3, 1.0), ((1.4, -0.2, 0.5), 0.6, 0.0)):
        inputs = _group_inputs(Albedo=albedo, Metallic=m, Smoothness=s)
        base = np.clip(albedo, 0, 1)
        for metal in metals:
            np.testing.assert_allclose(_evaluate(_source(metal.inputs["Base Color"]), inputs),
                                       0.04 * (1 - m) + base * m, rtol=1e-6, atol=1e-7)
            assert _evaluate(_source(metal.inputs["Roughness"]), inputs) == \
                pytest.approx(max(1 - s, math.sqrt(0.002)), rel=1e-6)
        np.testing.assert_allclose(_evaluate(_source(diffuse.inputs["Color"]), inputs),
                                   base * 0.96 * (1 - m), rtol=1e-6, atol=1e-7)


# --- A render where path tracing matters ----------------------------------------------------

SIZE, SAMPLES = 64, 64
# (albedo, metallic, smoothness): a copper-like metal and a blue dielectric
SPHERES = (dict(albedo=(0.95, 0.64, 0.54), metallic=1.0, smoothness=0.6),
           dict(albedo=(0.2, 0.35, 0.8), metallic=0.0, smoothness=0.45))
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


def _diffuse_material(name, colour):
    import bpy
    mat = bpy.data.materials.new(name)
    compat.use_nodes(mat)
    nt = mat.node_tree
    nt.nodes.clear()
    d = nt.nodes.new("ShaderNodeBsdfDiffuse")
    d.inputs["Color"].default_value = tuple(colour) + (1.0,)
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    nt.links.new(d.outputs["BSDF"], out.inputs["Surface"])
    return mat


def _emission_material(name, colour):
    import bpy
    mat = bpy.data.materials.new(name)
    compat.use_nodes(mat)
    nt = mat.node_tree
    nt.nodes.clear()
    e = nt.nodes.new("ShaderNodeEmission")
    e.inputs["Color"].default_value = tuple(colour) + (1.0,)
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    nt.links.new(e.outputs["Emission"], out.inputs["Surface"])
    return mat


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
        self.grey = _diffuse_material("grey", (0.5, 0.5, 0.5))
        self.red = _diffuse_material("red", (0.8, 0.05, 0.05))
        bpy.ops.mesh.primitive_plane_add(size=20)
        self.floor = bpy.context.active_object
        bpy.ops.mesh.primitive_cube_add(size=0.8, location=CUBE)
        self.cube = bpy.context.active_object
        self.spheres = []
        for location in LOCATIONS:
            bpy.ops.mesh.primitive_uv_sphere_add(segments=48, ring_count=24, radius=0.5,
                                                 location=location)
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

    def render(self, tmp, name, spheres, floor=None, cube=None, shader="nodes", seed=0,
               world=True, samples=SAMPLES, pixel_centres=False):
        """The linear image (float64, rows top-down as read_image gives them)."""
        from addon.blender import renderer
        from addon.core.compare import read_image
        for obj, mat in zip(self.spheres, spheres):
            self._set(obj, mat)
        self._set(self.floor, floor or self.grey)
        self._set(self.cube, cube or self.red)
        self.scene.world = self.world if world else None
        renderer.configure(self.scene, shader, "full", samples, seed=seed, path_traced=True,
                           pixel_centres=pixel_centres)
        image = renderer.render_result(tmp / "log.txt")
        path = tmp / f"{name}.exr"
        renderer.save_exr(self.scene, image, path)
        return read_image(path).astype(np.float64)

    def masks(self, tmp):
        """The pixels whose centre sees sphere 0 or 1 (an emission render, one sample at each
        pixel centre, no world)."""
        black = _emission_material("id black", (0, 0, 0))
        image = self.render(tmp, "masks", (_emission_material("id 0", (1, 0, 0)),
                                           _emission_material("id 1", (0, 1, 0))),
                            floor=black, cube=black, world=False, samples=1,
                            pixel_centres=True)
        return [image[..., 0] > 0.5, image[..., 1] > 0.5]


def group_material(surface, name):
    """The node group (through the project's material builder) in the scene transport with the
    exact switches: height-correlated Smith G, Lambert, no energy compensation."""
    from addon.blender import materials
    from addon.core.model import ModelOptions
    options = ModelOptions(g_model="smith_ggx_correlated", diffuse_model="lambert",
                           energy="none", light_transport="scene", ibl="split_sum")
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
    node.script = text
    errors = []
    cycles.osl.update_script_node(node, lambda kind, msg: errors.append(msg)
                                  if 'ERROR' in kind else None)
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
        "principled": scene.render(tmp, "principled", (
            principled_metal(SPHERES[0], "principled metal"), group[1])),
        "osl": scene.render(tmp, "osl", tuple(osl_reference(s, f"osl {k}")
                                              for k, s in enumerate(SPHERES)), shader="osl"),
        # the group with a grey cube in place of the red one
        "grey cube": scene.render(tmp, "grey cube", group, cube=scene.grey),
    }


@pytest.fixture(scope="module")
def renders(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("scene-transport-nodes")
    scene, images = scene_renders(tmp)
    return images, scene.masks(tmp)


# The allowance on a mean (a sphere's pixels or the whole image), relative, per channel. The
# renders share the seed, so the group and a reference with the same closures draw the same
# random numbers along the same paths: measured (5.2.3) 0 against Principled, at most 1.1e-4
# against the OSL closures (whose float rounding differs a little), where another seed moves
# the spheres' means by up to 5e-3. Wrong closures, measured against the OSL reference: Roughness
# = alpha, not sqrt(alpha), +2.4% (metal) and +3.7% (dielectric); Edge Tint 0.6, -2%;
# Multiscatter GGX, +5% and +0.4%; Oren-Nayar roughness 0.5, -6.5% (dielectric); a physical
# conductor Fresnel, -34% to +176%.
MEAN_RTOL = 2e-3


def _means(image, mask=None):
    return image[mask].mean(0) if mask is not None else image.mean((0, 1))


def _check_means(got, want, masks, which):
    for label, mask in [("image", None)] + [(f"sphere {k}", masks[k]) for k in which]:
        a, b = _means(got, mask), _means(want, mask)
        rel = np.abs(a - b) / b
        assert (rel < MEAN_RTOL).all(), (label, a, b, rel)


def test_the_metal_sphere_equals_a_principled_metal(renders):
    """Principled BSDF, metallic 1, GGX, Roughness = 1 - smoothness: the model's metal (specColor
    = albedo, diffColor = 0) as a closure Cycles path traces; the dielectric sphere is the
    group in both renders."""
    images, masks = renders
    assert masks[0].sum() > 200 and masks[1].sum() > 200
    _check_means(images["group"], images["principled"], masks, (0,))


def test_both_spheres_equal_the_model_as_osl_closures(renders):
    """generalized_schlick_bsdf(specColor, f90 = 1, exponent 5, GGX, alpha) + diffColor x
    diffuse(N), an independent spelling of the model's closures (Schlick's Fresnel written out,
    not F82-tint), path traced in the same scene: the metal and the dielectric sphere, and the
    whole image (the floor sees both spheres)."""
    images, masks = renders
    got, want = images["group"], images["osl"]
    _check_means(got, want, masks, (0, 1))
    # pixel by pixel: far below the noise of one render (a median of 1.8e-2 between seeds)
    assert np.median(np.abs(got - want)) < 2e-3


def test_the_group_sees_the_other_objects(renders):
    """The scene is one where path tracing matters: the red cube, seen in the metal sphere and
    lighting the floor, moves the means far beyond the allowance (a lab emission, which sees
    only the world, would not change at all)."""
    images, masks = renders
    red, grey = images["group"], images["grey cube"]
    for mask in (None, masks[0]):
        rel = (_means(grey, mask) - _means(red, mask)) / _means(red, mask)
        assert rel[1] > 5 * MEAN_RTOL and rel[2] > 5 * MEAN_RTOL, rel
