"""What differs between the Blender versions the add-on supports (addon/blender/compat.py),
measured on the running one, and renders that may crash Blender run in child processes: a
segmentation fault fails a test instead of killing the test run."""

import re
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from helpers import ROOT
from addon.blender import compat
from addon.core import env_importance, ibl_bake, osl_source

SHADER = osl_source.source()  # the shader with its parts inlined


def _child(code: str, timeout=240) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=timeout, cwd=ROOT
    )


@pytest.mark.parametrize(
    "shader,ibl",
    [
        ("osl", "reference"),
        ("osl", "split_sum"),
        ("osl", "unity"),
        ("nodes", "split_sum"),
        ("principled", "reference"),
    ],
)
def test_each_shader_renders_in_a_child_process(tmp_path, shader, ibl):
    """The command line's render, as a user runs it; exit 139 (or -11) is Blender crashing."""
    p = subprocess.run(
        [
            sys.executable,
            str(ROOT / "scripts" / "ctlab.py"),
            "render",
            "--shader",
            shader,
            "--ibl",
            ibl,
            "--grid",
            "2x2",
            "--size",
            "32",
            "--samples",
            "2",
            "--out",
            str(tmp_path / "out"),
        ],
        capture_output=True,
        text=True,
        timeout=240,
        cwd=ROOT,
    )
    assert p.returncode == 0, f"exit {p.returncode}:\n{p.stdout[-1500:]}\n{p.stderr[-1500:]}"
    assert (tmp_path / "out" / "render.exr").is_file()


def test_osl_texture_convention_is_what_compat_says(tmp_path):
    """OSL's texture() of a file, measured in a child process: which row t = 0 reads (the file's
    top up to 5.1, its bottom from 5.2: compat.osl_texture_rows_bottom_up) and that a lookup at
    a texel's centre returns that texel exactly, as the shader's table reads assume."""
    code = textwrap.dedent(f"""
        import sys, json
        sys.path.insert(0, {str(ROOT)!r})
        import bpy
        bpy.utils.expose_bundled_modules()
        import numpy as np
        from addon.core import compare
        from addon.blender import renderer
        from addon.core.hdri import write_float_exr
        grid = np.zeros((4, 8, 3), np.float32)
        grid[..., 0] = np.arange(8)[None, :]            # R: the column
        grid[..., 1] = np.arange(4)[:, None]            # G: the row, 0 = the file's first
        write_float_exr(__import__("pathlib").Path({str(tmp_path / "grid.exr")!r}), grid)
        src = '''shader probe(string f = "", float ps = 0.5, float pt = 0.5,
                                output closure color BSDF = 0) {{
            color c = texture(f, ps, pt, "interp", "linear", "swrap", "clamp", "twrap", "clamp");
            BSDF = c * emission();
        }}'''
        bpy.ops.wm.read_factory_settings(use_empty=True)
        scene = bpy.context.scene
        bpy.ops.mesh.primitive_plane_add(size=100)
        cam = bpy.data.objects.new("cam", bpy.data.cameras.new("cam"))
        scene.collection.objects.link(cam)
        cam.location = (0, 0, 5)
        scene.camera = cam
        scene.render.resolution_x = scene.render.resolution_y = 4
        mat = bpy.data.materials.new("probe")
        if mat.node_tree is None:
            mat.use_nodes = True
        nt = mat.node_tree
        nt.nodes.clear()
        text = bpy.data.texts.new("probe.osl")
        text.from_string(src)
        node = nt.nodes.new("ShaderNodeScript")
        node.mode = 'INTERNAL'
        import tempfile
        tempfile.tempdir = {str(tmp_path)!r}  # where Cycles leaves its .oso
        node.script = text
        from cycles import osl
        osl.update_script_node(node, lambda kind, msg: None)
        nt.links.new(node.outputs[0], nt.nodes.new("ShaderNodeOutputMaterial").inputs["Surface"])
        bpy.context.object.data.materials.append(mat)
        node.inputs["f"].default_value = {str(tmp_path / "grid.exr")!r}
        out = {{}}
        for name, s, t in (("centre", 2.5 / 8, 0.5 / 4), ("corner", 3 / 8, 1 / 4)):
            node.inputs["ps"].default_value, node.inputs["pt"].default_value = s, t
            renderer.configure(scene, "osl", "D", 1)
            renderer.render(scene, __import__("pathlib").Path({str(tmp_path)!r}) / name, {{}})
            out[name] = compare.read_image(
                __import__("pathlib").Path({str(tmp_path)!r}) / name / "render.exr")[1, 1].tolist()
        print("PROBE=" + json.dumps(out))
    """)
    p = _child(code)
    assert p.returncode == 0, f"exit {p.returncode}:\n{p.stdout[-1500:]}\n{p.stderr[-1500:]}"
    out = __import__("json").loads(p.stdout.split("PROBE=")[1].splitlines()[0])
    first_row = 3.0 if compat.osl_texture_rows_bottom_up() else 0.0
    # t = 1/8 is the centre of the first row counted from t = 0's side
    np.testing.assert_allclose(out["centre"][:2], [2.0, first_row], atol=1e-6)
    # a texel corner: the mean of four texels (columns 2, 3; rows 0, 1 or 3, 2)
    np.testing.assert_allclose(out["corner"][:2], [2.5, abs(first_row - 0.5)], atol=1e-4)


def _define(name: str) -> int:
    match = re.search(rf"^#define {name} (\d+)$", SHADER, re.M)
    assert match, f"the shader defines no {name}"
    return int(match[1])


def test_the_shaders_table_sizes_are_the_add_ons():
    """The shader reads the tables at texel centres of sizes it names itself; they must be
    the sizes the add-on writes (a table of another size would be read between texels)."""
    assert _define("DFG_SIZE") == ibl_bake.DFG_SIZE
    assert _define("ENV_TABLE_SIZE") == env_importance.TABLE_SIZE
    assert _define("ENV_TILE_ROWS") == env_importance.TILE_ROWS
    assert _define("ENV_TILE_COLS") == env_importance.TILE_COLS
    assert _define("IBL_LEVELS") == ibl_bake.LEVEL_COUNT
    for k in range(1, ibl_bake.LEVEL_COUNT):
        assert _define(f"LEVEL_{k}_WIDTH") == ibl_bake.LEVEL_WIDTHS[k]
    assert _define("IRRADIANCE_WIDTH") == ibl_bake.IRRADIANCE_WIDTH


def test_the_shader_avoids_what_crashes_or_misreads_on_some_version():
    """gettextureinfo() crashes Cycles 5.2 while it optimises the shader; a texture() whose file
    name varies while shading (format() of a varying level) reads no image there; only
    lookup() calls texture(), so every read turns rows over where the Blender needs it."""
    code = re.sub(r"//[^\n]*", "", SHADER)
    assert "gettextureinfo" not in code
    assert len(re.findall(r"\btexture\s*\(", code)) == 1, "texture() outside lookup()"
    for call in re.findall(r'format\("%s/[^"]*"', code):
        assert "%d" not in call, call
