"""The node group (node_groups/cook_torrance.toml, built by addon/node_group.py) against the
OSL shader: the same scene, every view, at pixel centres, rendered by Cycles with OSL off
(SVM, the GPU path) for the group and on for the shader."""

import numpy as np
import pytest

from conftest import render, sphere_pixels
from addon.params import LIGHTING_VIEWS, TERM_VIEWS

ALL_VIEWS = TERM_VIEWS + LIGHTING_VIEWS
# (model, the views it changes): the second case flips every switch
CASES = {
    "seed": (dict(), ALL_VIEWS),
    "smith_lambert_unity": (dict(g_model="smith_ggx_correlated", diffuse_model="lambert",
                                 units="unity", ibl="unity"),
                            ("NdotH", "G", "specular_brdf", "diffuse_brdf") + LIGHTING_VIEWS),
}
# no Sun shadow: the node group cannot trace one (SPEC "Lighting": it may skip the shadow)
SCENE = dict(grid=(3, 4), size=64, samples=1, pixel_centres=True, sun_shadow=False,
             albedo=(1.0, 0.766, 0.336), sun_to_light=(-0.3, -0.6, 0.74))


@pytest.fixture(scope="module", params=list(CASES))
def both(request, tmp_path_factory):
    model, views = CASES[request.param]
    model = dict({"ibl": "split_sum"}, **model)
    base = tmp_path_factory.mktemp(f"nodes-{request.param}")
    osl, scene = render(base / "osl", shader="osl", view=views, **SCENE, **model)
    nodes, _ = render(base / "nodes", shader="nodes", view=views, **SCENE, **model)
    mask = np.zeros((scene["height"], scene["width"]), dtype=bool)
    alpha = np.zeros(mask.shape)
    for cell in scene["cells"]:
        m = sphere_pixels(scene, cell)
        mask |= m
        alpha[m] = max((1 - cell["smoothness"]) ** 2, 0.002)
    return osl, nodes, mask, alpha


def _tolerance(view, osl, mask, alpha):
    """1e-5 relative (1e-6 absolute). Where D enters, float32 rounding of n.h is amplified by
    D's conditioning near the peak, 4 (n.h)^2 |a^2 - 1| / ((n.h)^2 (a^2 - 1) + 1), as in
    test_term_views; the allowance is that condition number times 3e-7, never below 1e-5."""
    want = np.abs(osl[view][mask].astype(np.float64))
    tol = np.maximum(1e-5 * want, 1e-6)
    if view in ("D", "specular_brdf", "direct_specular", "direct", "full"):
        nh = osl["NdotH"][mask][:, 0].astype(np.float64)
        a2 = alpha[mask] ** 2
        cond = 4 * nh ** 2 * np.abs(a2 - 1) / (nh ** 2 * (a2 - 1) + 1) * 3e-7
        tol = np.maximum(tol, cond[:, None] * want)
    return tol


@pytest.mark.parametrize("view", TERM_VIEWS + ("direct", "direct_diffuse", "direct_specular"))
def test_term_and_direct_views_equal_the_osl_shader(both, view):
    osl, nodes, mask, alpha = both
    if view not in nodes:
        pytest.skip("this case does not change the view")
    got = nodes[view][mask].astype(np.float64)
    want = osl[view][mask].astype(np.float64)
    bad = np.abs(got - want) > _tolerance(view, osl, mask, alpha)
    assert not bad.any(), (f"{view}: {int(bad.sum())} of {bad.size} values differ; "
                           f"nodes {got[bad][:3]} osl {want[bad][:3]}")


@pytest.mark.parametrize("view", ("indirect_diffuse", "indirect_specular", "full"))
def test_baked_indirect_light_agrees_with_the_osl_shader(both, view):
    """Both look the same baked textures up, OIIO's texture() in OSL and Cycles' image
    textures in the group: equal but for interpolation rounding, which a sun's sharp
    reflection on the mirror spheres magnifies at a few pixels."""
    osl, nodes, mask, _ = both
    got = nodes[view][mask].astype(np.float64)
    want = osl[view][mask].astype(np.float64)
    rel = np.abs(got - want) / np.maximum(np.abs(want), 1e-4)
    assert np.median(rel) < 1e-4 and np.percentile(rel, 99) < 5e-3, (
        np.median(rel), np.percentile(rel, 99))
    assert abs(got.mean() - want.mean()) < 1e-3 * want.mean()


def _user_scene(tmp_path):
    """A scene a user might make, with no sphere matrix: a UV sphere, a camera, the world HDRI,
    and images for albedo and a tangent-space normal map."""
    import bpy
    from addon import renderer, scene_builder
    from addon.paths import bundled_hdri
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    s = scene_builder.MatrixSettings(width=64, height=64)
    scene.world = scene_builder.build_world(s, scene_builder.load_image(bundled_hdri("forest")))
    bpy.ops.mesh.primitive_uv_sphere_add(segments=64, ring_count=32, radius=1.0)
    sphere = bpy.context.active_object
    bpy.ops.object.shade_smooth()
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    cam.data.type = 'ORTHO'
    cam.data.ortho_scale = 2.4
    cam.location = (0, -10, 0)
    cam.rotation_euler = (np.pi / 2, 0, 0)
    scene.collection.objects.link(cam)
    scene.camera = cam
    scene.render.resolution_x = scene.render.resolution_y = 64
    u = np.linspace(0, 1, 32)
    checker = np.zeros((32, 32, 4), dtype=np.float32)
    checker[..., 0] = u[None, :]
    checker[..., 1] = u[:, None]
    checker[..., 2] = 0.3
    checker[..., 3] = 1
    albedo = bpy.data.images.new("user albedo", 32, 32, float_buffer=True)
    albedo.pixels.foreach_set(checker.ravel())
    bumps = np.zeros((32, 32, 4), dtype=np.float32)
    bumps[..., 0] = 0.5 + 0.35 * np.sin(6 * np.pi * u)[None, :]
    bumps[..., 1] = 0.5
    bumps[..., 2] = 0.8
    bumps[..., 3] = 1
    normal = bpy.data.images.new("user normal", 32, 32, float_buffer=True, is_data=True)
    normal.pixels.foreach_set(bumps.ravel())
    return scene, sphere, albedo, normal, renderer


def _user_material(group, albedo, normal):
    """Image Texture -> Albedo, Image Texture -> Normal Map -> Normal, group -> Material Output,
    as an artist wires it in the shader editor."""
    import bpy
    mat = bpy.data.materials.new("User Material")
    mat.use_nodes = True
    nt = mat.node_tree
    nt.nodes.clear()
    g = nt.nodes.new("ShaderNodeGroup")
    g.node_tree = group
    tex = nt.nodes.new("ShaderNodeTexImage")
    tex.image = albedo
    ntex = nt.nodes.new("ShaderNodeTexImage")
    ntex.image = normal
    nmap = nt.nodes.new("ShaderNodeNormalMap")
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    nt.links.new(tex.outputs["Color"], g.inputs["Albedo"])
    nt.links.new(ntex.outputs["Color"], nmap.inputs["Color"])
    nt.links.new(nmap.outputs["Normal"], g.inputs["Normal"])
    g.inputs["Metallic"].default_value = 0.3
    g.inputs["Smoothness"].default_value = 0.6
    nt.links.new(g.outputs["Emission"], out.inputs["Surface"])
    return mat, g


def test_group_works_in_a_users_own_material(tmp_path):
    """The group in a user's material (textures and a normal map wired to it, no sphere
    matrix) renders the same views as the OSL shader given the same textures."""
    from addon import ibl_bake, materials, node_group
    from addon.compare import read_image
    from addon.params import ModelOptions
    from addon.paths import bundled_hdri
    scene, sphere, albedo, normal, renderer = _user_scene(tmp_path)
    bake = ibl_bake.bake(bundled_hdri("forest"))
    group = node_group.build_group()
    node_group.set_bake(group, bake)
    user, g = _user_material(group, albedo, normal)
    lighting = materials.Lighting(sun_to_light=(-0.4, -0.6, 0.7), sun_irradiance=(2, 2, 2),
                                  ibl_bake=str(bake))
    materials.set_group_lighting(g, lighting)
    osl = materials.cook_torrance_material("OSL twin", ModelOptions(ibl="split_sum"), lighting,
                                           albedo=(0, 0, 0), metallic=0.3, smoothness=0.6,
                                           albedo_image=albedo, normal_map=normal)
    images = {}
    for name, mat, shader in (("nodes", user, "nodes"), ("osl", osl, "osl")):
        sphere.data.materials.clear()
        sphere.data.materials.append(mat)
        for view in ("albedo", "normal", "D", "indirect"):
            options = ModelOptions(view=view, ibl="split_sum", sun_shadow=False)
            if shader == "nodes":
                materials.set_group_options(g, options)
            else:
                materials.set_options(mat, options)
            renderer.configure(scene, shader, view, 1, pixel_centres=True)
            out = tmp_path / name / view
            renderer.render(scene, out, {}, log_path=tmp_path / "log.txt")
            images[name, view] = read_image(out / "render.exr")
    centre = np.zeros((64, 64), dtype=bool)
    ys, xs = np.mgrid[0:64, 0:64]
    centre[(xs + 0.5 - 32) ** 2 + (ys + 0.5 - 32) ** 2 < (0.9 * 32 / 1.2) ** 2] = True
    tilted = images["osl", "normal"][centre] @ np.array([0, -1, 0])
    assert np.std(images["osl", "albedo"][centre][:, 0]) > 0.05    # the texture is there
    for view in ("albedo", "normal", "D"):
        a, b = images["nodes", view][centre], images["osl", view][centre]
        np.testing.assert_allclose(a, b, rtol=1e-4, atol=1e-5, err_msg=view)
    a, b = images["nodes", "indirect"][centre], images["osl", "indirect"][centre]
    assert np.median(np.abs(a - b) / np.maximum(np.abs(b), 1e-4)) < 1e-3
    # the normal map tilts the normal away from the geometry's (whose n.v is 1 at the centre)
    assert tilted.min() < 0.95
