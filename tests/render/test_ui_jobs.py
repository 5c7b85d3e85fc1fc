"""The add-on's background jobs from the interface: the render comparison and the scene
comparison (progress, cancel, the result in the Image Editor), the BRDF plot of the active
material, and a scene comparison refused without a camera."""

import json
import math

import bpy
import pytest
from mathutils import Vector

from addon.blender import model_node
from addon.ui import operators


def test_render_comparison_in_the_background(addon, tmp_path):
    """The job runs in another process: progress rises to 1, the report is written; a second
    job cancelled after its first render keeps that render whole and leaves no partial file."""
    import time

    wm = bpy.context.window_manager
    kw = dict(rows=2, cols=2, size=32, samples=2, open_report=False)

    def run_until(done, limit=300):
        start = time.monotonic()
        seen = []
        while time.monotonic() - start < limit:
            operators._job_tick()  # what the timer calls (no event loop headless)
            seen.append(wm.ctlab_job_progress)
            if done():
                return seen
            time.sleep(0.2)
        raise AssertionError(f"timed out: {wm.ctlab_job_message}")

    # the scene a user has after Build Sphere Matrix: its default Sun has negative x and y
    # (which the job's command line used to misread), a world with strength and rotation
    assert bpy.ops.ctlab.build_sphere_matrix(rows=2, cols=2, resolution=32) == {'FINISHED'}
    background, mapping = (
        next(n for n in bpy.context.scene.world.node_tree.nodes if n.bl_idname == kind)
        for kind in ("ShaderNodeBackground", "ShaderNodeMapping")
    )
    background.inputs["Strength"].default_value = 1.5
    mapping.inputs["Rotation"].default_value[2] = -0.5  # radians
    sun = next(o for o in bpy.context.scene.objects if o.type == 'LIGHT' and o.data.type == 'SUN')
    to_light = tuple(sun.matrix_world.to_quaternion() @ Vector((0.0, 0.0, 1.0)))
    assert min(to_light[:2]) < 0
    out = tmp_path / "full"
    assert bpy.ops.ctlab.render_comparison(directory=str(out), **kw) == {'FINISHED'}
    with pytest.raises(RuntimeError, match="already running"):
        bpy.ops.ctlab.render_comparison(directory=str(out), **kw)
    seen = run_until(lambda: operators.JOBS["comparison"].state != "running")
    job = operators.JOBS["comparison"]
    assert job.state == "done", "\n".join(job.lines[-20:])
    assert wm.ctlab_job_progress == 1.0 and (out / "report.html").is_file()
    assert seen == sorted(seen) and len(set(seen)) >= 3, seen  # it moved, never backwards
    scene = json.loads((out / "cook_torrance" / "scene.json").read_text())
    assert scene["sun"]["to_light"] == pytest.approx(to_light, abs=1e-6)
    assert scene["sun"]["irradiance"] == pytest.approx([sun.data.energy] * 3)
    assert scene["hdri_strength"] == pytest.approx(1.5)
    assert scene["hdri_rotation_deg"] == pytest.approx(math.degrees(-0.5))
    assert scene["hdri"].endswith("forest.exr")
    assert not bpy.app.timers.is_registered(operators._job_tick) or operators._job_tick() is None

    out = tmp_path / "cancelled"
    bpy.ops.ctlab.render_comparison(directory=str(out), **kw)
    run_until(lambda: (out / "cook_torrance" / "scene.json").is_file())
    assert bpy.ops.ctlab.cancel_comparison() == {'FINISHED'}
    run_until(lambda: operators.JOBS["comparison"].state == "cancelled", limit=60)
    from addon.core.compare import read_image

    assert read_image(out / "cook_torrance" / "render.exr").shape == (32, 32, 3)
    assert not (out / "report.html").exists()
    # nothing half-written; the task graph's markers (.tasks/) record the renders that
    # finished, so a rerun resumes (docs/usage.md, "Batch jobs as task graphs")
    leftovers = [
        p.name
        for p in out.rglob("*")
        if "partial" in p.name or (p.name.startswith(".") and p.name != ".tasks")
    ]
    assert not leftovers, leftovers
    assert all(m.suffix == ".json" for m in (out / ".tasks").iterdir())

    with pytest.raises(RuntimeError, match="output folder not writable"):
        bpy.ops.ctlab.render_comparison(directory="/proc/ctlab", **kw)


def test_brdf_plot_of_the_active_material(addon, tmp_path):
    """BRDF Plot runs ``ctlab plot`` on the material's own values and switches in another
    process and loads plot.png as the image "Cook-Torrance BRDF Plot" (reloaded by a second
    plot); a linked input is reported and plotted at its socket's value; a material that is
    not the model cannot be plotted."""
    import time

    cube = bpy.data.objects["Cube"]
    bpy.context.view_layer.objects.active = cube
    bpy.ops.ctlab.new_material(implementation="nodes")
    mat = cube.active_material
    node = model_node.find(mat)
    model_node.surface_input(node, "metallic").default_value = 1.0
    model_node.surface_input(node, "smoothness").default_value = 0.7
    model_node.surface_input(node, "albedo").default_value = (1.0, 0.5, 0.2, 1.0)
    model_node.set_option(node, "g_model", "smith_ggx_correlated")

    def plot(out, **kw):
        assert bpy.ops.ctlab.brdf_plot(directory=str(out), **kw) == {'FINISHED'}
        start = time.monotonic()
        while operators.JOBS["plot"].poll() == "running":
            assert time.monotonic() - start < 300, operators.JOBS["plot"].lines[-10:]
            time.sleep(0.2)
        operators._job_tick()
        job = operators.JOBS["plot"]
        assert job.state == "done", "\n".join(job.lines[-20:])
        return json.loads((out / "plot.json").read_text())

    data = plot(tmp_path / "a")
    p = data["parameters"]
    assert (p["metallic"], p["smoothness"], p["g_model"], p["shader"]) == (
        1.0,
        pytest.approx(0.7),
        "smith_ggx_correlated",
        "nodes",
    )
    assert p["albedo"] == pytest.approx([1.0, 0.5, 0.2])
    image = bpy.data.images[operators.PLOT_IMAGE]
    from addon.core.compare import read_image

    h, w, _ = read_image(tmp_path / "a" / "plot.png").shape
    assert tuple(image.size) == (w, h)
    assert bpy.context.window_manager.ctlab_plot_state == "done"

    # a textured smoothness: plotted at the socket's value, with a warning
    tex = mat.node_tree.nodes.new("ShaderNodeValue")
    tex.outputs[0].default_value = 0.1
    mat.node_tree.links.new(tex.outputs[0], model_node.surface_input(node, "smoothness"))
    data = plot(tmp_path / "b", compare_g=True)
    assert data["parameters"]["smoothness"] == pytest.approx(0.7)
    assert [v["tag"] for v in data["variants"]] == ["", "g-cook_torrance", "g-unity_smith_joint"]
    assert bpy.data.images[operators.PLOT_IMAGE].filepath.endswith("b/plot.png")
    argv, notes = operators.plot_command(node, tmp_path)
    assert any("smoothness is linked" in n for n in notes)

    # a plot that fails in its process (a folder where it writes lobe.svg) says why, and
    # the image keeps the last plot
    (tmp_path / "d" / "lobe.svg").mkdir(parents=True)
    assert bpy.ops.ctlab.brdf_plot(directory=str(tmp_path / "d")) == {'FINISHED'}
    start = time.monotonic()
    while operators.JOBS["plot"].poll() == "running":
        assert time.monotonic() - start < 300
        time.sleep(0.2)
    operators._job_tick()
    wm = bpy.context.window_manager
    assert (
        wm.ctlab_plot_state == "failed" and "holds a folder named lobe.svg" in wm.ctlab_plot_message
    ), wm.ctlab_plot_message
    assert not (tmp_path / "d" / "plot.json").exists()
    assert bpy.data.images[operators.PLOT_IMAGE].filepath.endswith("b/plot.png")

    cube.active_material = bpy.data.materials["Material"]
    with pytest.raises(RuntimeError, match="poll"):
        bpy.ops.ctlab.brdf_plot(directory=str(tmp_path / "c"))


def test_scene_comparison_in_the_background(addon, tmp_path):
    """Compare Scene with Principled: the open scene (never written) through its camera, its
    Cook-Torrance material against the Principled conversion, in a background process; the
    report and the per-material metrics are written and the file's copy is removed."""
    import time
    from addon.blender import demo_scene, light_sync, materials
    from addon.core.model import ModelOptions

    scene, sphere, _other = demo_scene.build("hdri", 48, 36)
    register_scene = bpy.context.scene
    assert register_scene == scene
    mat = materials.model_material(
        "CT",
        "nodes",
        ModelOptions(
            light_transport="scene",
            g_model="smith_ggx_correlated",
            diffuse_model="lambert",
            ibl="split_sum",
        ),
        **demo_scene.METAL,
    )
    demo_scene.set_material(sphere, mat)
    light_sync.sync_material(mat, scene)
    out = tmp_path / "scene"
    # the operator's overrides reach the command line: here the OSL shader for the node
    # group's material (Smith and Lambert: the closures are the model exactly)
    assert bpy.ops.ctlab.scene_comparison(
        directory=str(out),
        size=48,
        samples=4,
        shader="osl",
        g_model="smith_ggx_correlated",
        camera="Camera",
        open_report=False,
    ) == {'FINISHED'}
    job = operators.JOBS["comparison"]
    command = " ".join(job.process.args)
    assert "'--shader=osl'" in command and "'--g=smith_ggx_correlated'" in command
    assert "'--camera=Camera'" in command and "--diffuse" not in command
    start = time.monotonic()
    while job.poll() in ("running", "cancelling") and time.monotonic() - start < 300:
        operators._job_tick()
        time.sleep(0.2)
    operators._job_tick()
    assert job.state == "done", "\n".join(job.lines[-20:])
    assert (out / "report.html").is_file()
    metrics = json.loads((out / "metrics.json").read_text())
    (entry,) = [m for m in metrics["materials"] if m["name"] == "CT"]
    assert entry["pixels"] > 50 and entry["ciede2000_mean"] < 2.0
    assert not job.staging.exists()


def test_a_scene_comparison_needs_a_camera(addon):
    with pytest.raises(RuntimeError, match="no camera named 'Cube'"):
        bpy.ops.ctlab.scene_comparison(size=32, samples=1, camera="Cube")
    with pytest.raises(RuntimeError, match="no camera named 'Nowhere'"):
        bpy.ops.ctlab.scene_comparison(size=32, samples=1, camera="Nowhere")
    bpy.ops.wm.read_factory_settings(use_empty=True)
    with pytest.raises(RuntimeError, match="no camera"):
        bpy.ops.ctlab.scene_comparison(size=32, samples=1)
