"""docs/bad-input.md, case by case: each bad input gets its message, exit status 2 (or an
ERROR report from the operator) and writes nothing. The command line runs in-process
(cli.main, what scripts/ctlab.py exits with); one case runs as a real process too."""

import re
import types
from pathlib import Path

import bpy
import pytest

from addon.jobs import cli

from addon.ui import operators
from helpers import ROOT, bad_images, fake_render


# ID -> (argv, message). @BAD:<key> is a bad image from conftest.bad_images; @FILE a plain file.
RENDER = ["render", "--shader", "osl", "--size", "32", "--grid", "1x1"]
CLI_CASES = {
    "hdri-missing": (RENDER + ["--hdri", "@BAD:HDRI not found"], "HDRI not found"),
    "hdri-not-float": (RENDER + ["--hdri", "@BAD:not floating point"], "not floating point"),
    "hdri-one-channel": (["bake", "@BAD:1 channel"], "1 channel(s)"),
    "hdri-not-2-1": (RENDER + ["--hdri", "@BAD:not 2:1"], "not 2:1 equirectangular"),
    "hdri-truncated": (["bake", "@BAD:corrupt or truncated"], "corrupt or truncated"),
    "hdri-unreadable": (RENDER + ["--hdri", "@BAD:HDRI unreadable"], "HDRI unreadable"),
    "grid-malformed": (RENDER[:-2] + ["--grid", "7by7"], "malformed grid '7by7'"),
    "grid-range": (RENDER[:-2] + ["--grid", "40x2"], "grid 40x2 out of range"),
    "size-range": (RENDER[:3] + ["--size", "5"], "image size 5 out of range"),
    "samples-range": (RENDER + ["--samples", "0"], "samples 0 out of range"),
    "env-samples-range": (RENDER + ["--env-samples", "0"], "env samples 0 out of range"),
    "vector-malformed": (RENDER + ["--sun-dir", "1,2"], "malformed sun direction"),
    "sun-zero": (RENDER + ["--sun-dir", "0,0,0"], "is not a non-zero 3-vector"),
    "strength-negative": (RENDER + ["--sun-strength", "-1"], "sun strength -1.0 out of range"),
    "albedo-range": (RENDER + ["--albedo", "2,0,0"], "albedo (2.0, 0.0, 0.0) out of range"),
    "view-unknown": (RENDER + ["--view", "Q"], "unknown view 'Q'"),
    "g-unknown": (RENDER + ["--g", "beckmann"], "unknown G 'beckmann'"),
    "ibl-unknown": (RENDER + ["--ibl", "probe"], "unknown IBL 'probe'"),
    "energy-unknown": (RENDER + ["--energy", "more"], "unknown energy 'more'"),
    "transport-unknown": (
        RENDER + ["--light-transport", "probe"],
        "unknown light transport 'probe'",
    ),
    "transport-scene-unity": (
        RENDER + ["--light-transport", "scene", "--units", "unity"],
        "Unity's units (x pi on direct light) exist in the lab",
    ),
    "transport-scene-pixel-centres": (
        RENDER + ["--light-transport", "scene", "--pixel-centres"],
        "the scene transport is path traced",
    ),
    "ibl-nodes-reference": (
        ["render", "--shader", "nodes", "--ibl", "reference"],
        "the node group has no 'reference' indirect light",
    ),
    "shader-unknown": (["render", "--shader", "arnold"], "invalid choice: 'arnold'"),
    "eevee-osl": (RENDER + ["--engine", "eevee"], "--engine eevee renders the node group only"),
    "out-unwritable": (
        ["render", "--shader", "osl", "--out", "@FILE/sub"],
        "output folder not writable",
    ),
    "cache-unusable": (["bake", "@FOREST"], "cache folder not usable"),
    "compare-not-render": (["compare", "@EMPTY", "@EMPTY"], "is not a render folder"),
    "parity-hdri-unknown": (
        ["matrix", "--parity", "--parity-hdris", "moon"],
        "unknown bundled HDRI in --parity-hdris 'moon'",
    ),
    # numbers: finite in float32, in Blender's range
    "strength-overflow": (RENDER + ["--hdri-strength", "1e39"], "hdri strength 1e+39 out of range"),
    "strength-huge": (RENDER + ["--sun-strength", "2e6"], "sun strength 2000000.0 out of range"),
    "rotation-nonfinite": (RENDER + ["--hdri-rotation", "inf"], "hdri rotation inf out of range"),
    "seed-negative": (RENDER + ["--seed", "-1"], "seed -1 out of range; use 0 to 2147483647"),
    "seed-huge": (RENDER + ["--seed", "2147483648"], "seed 2147483648 out of range"),
    "sun-dir-nan": (RENDER + ["--sun-dir", "nan,0,1"], "malformed sun direction 'nan,0,1'"),
    "albedo-negative": (RENDER + ["--albedo", "-0.1,0.5,0.5"], "out of range; use three values"),
    "geometry-too-small": (
        RENDER[:3] + ["--grid", "16x16", "--size", "16"],
        "image size 16 is too small for a 16x16 grid",
    ),
    "matrix-geometry": (
        ["matrix", "--grid", "9x9", "--size", "32"],
        "image size 32 is too small for a 9x9 grid",
    ),
    # argparse, on one line
    "option-value-missing": (["render", "--shader"], "argument --shader: expected one argument"),
    "option-unknown": (RENDER + ["--colour", "red"], "unrecognized arguments: --colour red"),
    # paths
    "out-empty": (["render", "--shader", "osl", "--out", ""], "empty --out"),
    "out-too-long": (
        ["render", "--shader", "osl", "--out", "@LONG"],
        "--out is longer than this system allows",
    ),
    "out-is-input": (
        RENDER + ["--hdri", "@HDRI_IN_OUT", "--out", "@OUT_WITH_HDRI"],
        "is an input of this job",
    ),
    "bake-out-is-input": (
        ["bake", "@HDRI_IN_OUT_BAKE", "--out", "@OUT_WITH_BAKE_HDRI"],
        "is an input of this job",
    ),
    # compare: both folders checked whole before anything is written
    "compare-truncated": (["compare", "@RENDER:truncated", "@RENDER:good"], "image unreadable"),
    "compare-bad-json": (["compare", "@RENDER:good", "@RENDER:badjson"], "is not valid JSON"),
    "compare-bad-scene": (
        ["compare", "@RENDER:schema", "@RENDER:good"],
        "is not a render's description: 'width' is not a positive",
    ),
    "compare-nan": (["compare", "@RENDER:nan", "@RENDER:good"], "holds 1 NaN/Inf pixel(s)"),
    "compare-size-mismatch": (
        ["compare", "@RENDER:wrongsize", "@RENDER:good"],
        "but scene.json says 32x32",
    ),
    # --lights FILE.json (@LIGHTS:<key of LIGHTS_FILES>)
    "lights-missing": (RENDER + ["--lights", "@NOFILE"], "lights file"),
    "lights-not-json": (RENDER + ["--lights", "@LIGHTS:not-json"], "is not JSON"),
    "lights-not-list": (
        RENDER + ["--lights", "@LIGHTS:not-list"],
        "expected a non-empty list of lights",
    ),
    "lights-too-many": (
        RENDER + ["--lights", "@LIGHTS:too-many"],
        "9 lights; the model shades at most 8",
    ),
    "lights-type-unknown": (RENDER + ["--lights", "@LIGHTS:type"], 'unknown light type "LASER"'),
    "lights-key-unknown": (RENDER + ["--lights", "@LIGHTS:key"], "POINT light has no key 'power'"),
    "lights-key-other-type": (
        RENDER + ["--lights", "@LIGHTS:other-type"],
        "POINT light has no key 'spot_size'",
    ),
    "lights-energy-missing": (RENDER + ["--lights", "@LIGHTS:no-energy"], "energy is missing"),
    "lights-vector-shape": (
        RENDER + ["--lights", "@LIGHTS:shape"],
        "location must be a list of 3 numbers",
    ),
    "lights-nonfinite": (RENDER + ["--lights", "@LIGHTS:nan"], "energy must be finite"),
    "lights-negative": (RENDER + ["--lights", "@LIGHTS:negative"], "energy -5.0 out of range"),
    "lights-area-zero": (
        RENDER + ["--lights", "@LIGHTS:area-zero"],
        "an AREA light needs a size above 0",
    ),
    "lights-shape-unknown": (
        RENDER + ["--lights", "@LIGHTS:area-shape"],
        'unknown shape "TRIANGLE"',
    ),
    "lights-scale-negative": (RENDER + ["--lights", "@LIGHTS:mirrored"], "scale must be positive"),
    "lights-huge-number": (RENDER + ["--lights", "@LIGHTS:huge"], "energy out of range"),
    "lights-too-bright": (RENDER + ["--lights", "@LIGHTS:bright"], "the model takes at most 1e+09"),
    # ctlab plot
    "plot-metallic-range": (["plot", "--metallic", "2"], "metallic 2.0 out of range; use 0 to 1"),
    "plot-metallic-negative": (
        ["plot", "--metallic", "-0.5"],
        "metallic -0.5 out of range; use 0 to 1",
    ),
    "plot-metallic-nan": (["plot", "--metallic", "nan"], "metallic nan out of range"),
    "plot-smoothness-nonfinite": (
        ["plot", "--smoothness", "inf"],
        "smoothness inf out of range; use 0 to 1",
    ),
    "plot-albedo-range": (["plot", "--albedo", "-1,0,0"], "albedo -1.0 out of range"),
    "plot-compare-malformed": (["plot", "--compare", "g"], "malformed --compare 'g'"),
    "plot-compare-unknown": (["plot", "--compare", "g=phong"], "unknown g 'phong' in --compare"),
    "plot-view": (["plot", "--view", "full"], "view 'full' cannot be sliced"),
    "plot-shader": (["plot", "--shader", "principled"], "invalid choice: 'principled'"),
    "plot-out-unwritable": (["plot", "--out", "@FILE/sub"], "output folder not writable"),
    # the one path gate (core/paths.py; tests/render/test_paths.py has the properties)
    "path-blend-relative": (
        RENDER + ["--hdri", "//sky.exr"],
        "starts with '//', which Blender reads as relative",
    ),
    "path-backslash": (RENDER + ["--out", "a\\b"], "holds a backslash"),
    "hdri-name-too-long": (
        RENDER + ["--hdri", "@LONGNAME"],
        "HDRI is longer than this system allows",
    ),
    "out-too-deep": (RENDER + ["--out", "@DEEP"], "--out is longer than this system allows"),
    "lights-fifo": (RENDER + ["--lights", "@FIFO"], "is a named pipe (FIFO), not a regular"),
    "hdri-folder": (RENDER + ["--hdri", "@EMPTY"], "is a folder, not a regular file"),
    "blend-device": (
        ["scene", "/dev/zero", "--out", "@EMPTY/o"],
        "is a device, not a regular file",
    ),
    "lights-is-output": (
        RENDER + ["--lights", "@LIGHTS_IN_OUT", "--out", "@OUT_WITH_LIGHTS"],
        "is an input of this job",
    ),
    "out-blocked": (RENDER + ["--out", "@OUT_BLOCKED"], "is a folder where this job writes a file"),
    "out-in-cache": (RENDER + ["--out", "@IN_CACHE"], "is inside the cache folder"),
    "cache-unwritable": (["bake", "@FOREST"], "cache folder not usable"),
    "grid-unicode-digit": (RENDER[:-2] + ["--grid", "\u00b2x2"], "malformed grid"),
    "size-unicode-digit": (
        RENDER[:3] + ["--size", "\u0663\u0662"],
        "argument --size: invalid int value",
    ),
    "hdri-nan": (RENDER + ["--hdri", "@NAN_HDRI"], "HDRI holds 1 NaN/Inf pixel(s)"),
    "bake-nan": (["bake", "@NAN_HDRI", "--out", "@EMPTY/o"], "HDRI holds 1 NaN/Inf pixel(s)"),
}
LIGHTS_FILES = {
    "not-json": '[{"type": "SUN",',
    "not-list": '{"type": "SUN", "energy": 1}',
    "too-many": "[" + ", ".join(['{"type": "POINT", "energy": 10}'] * 9) + "]",
    "type": '[{"type": "LASER", "energy": 1}]',
    "key": '[{"type": "POINT", "energy": 1, "power": 3}]',
    "other-type": '[{"type": "POINT", "energy": 1, "spot_size": 0.5}]',
    "no-energy": '[{"type": "SUN"}]',
    "shape": '[{"type": "POINT", "energy": 1, "location": [1, 2]}]',
    "nan": '[{"type": "POINT", "energy": NaN}]',
    "negative": '[{"type": "POINT", "energy": -5}]',
    "area-zero": '[{"type": "AREA", "energy": 5, "size": 0}]',
    "area-shape": '[{"type": "AREA", "energy": 5, "shape": "TRIANGLE"}]',
    "mirrored": '[{"type": "SPOT", "energy": 5, "scale": [1, 1, -1]}]',
    "huge": '[{"type": "POINT", "energy": 1' + "0" * 400 + '}]',
    "bright": '[{"type": "POINT", "energy": 1e6, "exposure": 12}]',
}
OPERATOR_CASES = (
    "op-matrix-hdri",
    "op-bake-hdri",
    "op-convert-not-principled",
    "op-convert-not-model",
    "op-convert-no-material",
    "op-comparison-running",
    "op-comparison-out-backslash",
)


# The test files whose CASES (ID -> the test) hold rows of docs/bad-input.md, by subject
CASE_MODULES = (
    "test_paths",
    "test_writes",
    "test_cache_entries",
    "test_signals",
    "test_job_folder_input",
    "test_write_gate",
    "test_travel_folder",
    "test_textures",
    "test_datablocks",
    "test_export_names",
    "test_unity",
)


def _case_modules():
    import importlib

    return [importlib.import_module(name) for name in CASE_MODULES]


def test_the_docs_table_and_these_tests_list_the_same_cases():
    table = (ROOT / "docs" / "bad-input.md").read_text()
    documented = set(re.findall(r"^\| `([a-z0-9-]+)` \|", table, re.M))
    listed = set(CLI_CASES) | set(OPERATOR_CASES)
    for module in _case_modules():
        assert not listed & set(module.CASES), module.__name__
        listed |= set(module.CASES)
    assert documented == listed


def test_each_documented_case_names_a_test_here():
    """Each CASES entry of the files above names a test of its own file."""
    for module in _case_modules():
        missing = {k: v for k, v in module.CASES.items() if not callable(getattr(module, v, None))}
        assert not missing, (module.__name__, missing)


def _argv(case, tmp_path):
    import numpy as np
    from addon.core.hdri import write_float_exr

    images = bad_images(tmp_path)
    blocker = tmp_path / "a-file"
    blocker.write_text("x")
    (tmp_path / "empty").mkdir()
    from addon.blender.paths import bundled_hdri

    subs = {
        "@FOREST": str(bundled_hdri("forest")),
        "@EMPTY": str(tmp_path / "empty"),
        "@LONG": str(tmp_path / ("x" * 300)),
    }
    for name, file in (("@OUT_WITH_HDRI", "render.exr"), ("@OUT_WITH_BAKE_HDRI", "specular_0.exr")):
        folder = tmp_path / name.strip("@").lower()
        folder.mkdir()
        write_float_exr(folder / file, np.ones((32, 64, 3), np.float32))
        subs[name] = str(folder)
        subs["@HDRI_IN_OUT" + ("_BAKE" if "BAKE" in name else "")] = str(folder / file)
    import os

    subs["@LONGNAME"] = str(tmp_path / ("\u00e9" * 130 + ".exr"))  # 260 bytes
    subs["@DEEP"] = str(tmp_path.joinpath(*["d" * 200] * 5))
    os.mkfifo(tmp_path / "pipe.json")
    subs["@FIFO"] = str(tmp_path / "pipe.json")
    (tmp_path / "with-lights").mkdir()
    (tmp_path / "with-lights" / "scene.json").write_text('[{"type": "POINT", "energy": 1}]')
    subs["@OUT_WITH_LIGHTS"] = str(tmp_path / "with-lights")
    subs["@LIGHTS_IN_OUT"] = str(tmp_path / "with-lights" / "scene.json")
    (tmp_path / "blocked" / "render.png").mkdir(parents=True)
    subs["@OUT_BLOCKED"] = str(tmp_path / "blocked")
    subs["@IN_CACHE"] = str(tmp_path / "cache" / "o")
    nan = np.ones((32, 64, 3), np.float32)
    nan[1, 2, 0] = np.nan
    write_float_exr(tmp_path / "nan.exr", nan)
    subs["@NAN_HDRI"] = str(tmp_path / "nan.exr")
    argv = []
    for a in CLI_CASES[case][0]:
        if a.startswith("@BAD:"):
            a = str(images[a[5:]])
        elif a.startswith("@LIGHTS:"):
            lights = tmp_path / f"lights-{a[8:]}.json"
            lights.write_text(LIGHTS_FILES[a[8:]])
            a = str(lights)
        elif a == "@NOFILE":
            a = str(tmp_path / "no-such-lights.json")
        elif a.startswith("@RENDER:"):
            a = str(fake_render(tmp_path / f"render-{a[8:]}-{len(argv)}", a[8:]))
        for key in ("@EMPTY", "@FILE"):
            if a.startswith(key + "/"):
                a = subs.get(key, str(blocker)) + a[len(key) :]
        argv.append(subs.get(a, a))
    if argv[0] in ("render", "matrix", "plot") and "--out" not in argv:
        argv += ["--out", str(tmp_path / "out")]
    if argv[0] == "compare":
        argv += ["--out", str(tmp_path / "out")]
    return argv, blocker


@pytest.mark.parametrize("case", list(CLI_CASES))
def test_command_line_bad_input(case, tmp_path, capsys, monkeypatch):
    argv, blocker = _argv(case, tmp_path)
    cache = tmp_path / "cache"
    monkeypatch.setenv("CTLAB_CACHE", str(blocker / "cache" if case == "cache-unusable" else cache))
    if case == "cache-unwritable":  # exists, not writable (root: a system folder)
        from addon.core.files import probe_writable

        cache.mkdir()
        cache.chmod(0o555)
        if probe_writable(cache) is not None:
            monkeypatch.setenv("CTLAB_CACHE", str(cache))
        elif Path("/sys/kernel").is_dir() and probe_writable(Path("/sys/kernel")):
            monkeypatch.setenv("CTLAB_CACHE", "/sys/kernel")
        else:
            pytest.skip("no unwritable folder here")
    inputs = {p for p in tmp_path.rglob("*")}
    assert cli.main(argv) == cli.EXIT_BAD_INPUT
    err = capsys.readouterr().err.strip().splitlines()
    errors = [line for line in err if "error:" in line]
    assert len(errors) == 1 and CLI_CASES[case][1] in errors[0], err
    assert "Traceback" not in "\n".join(err)
    written = {p for p in tmp_path.rglob("*")} - inputs
    assert not written, written  # no output folder, file or cache entry


def test_exit_status_2_from_the_real_command(tmp_path):
    import subprocess
    import sys

    p = subprocess.run(
        [
            sys.executable,
            str(ROOT / "scripts" / "ctlab.py"),
            "render",
            "--shader",
            "osl",
            "--out",
            str(tmp_path / "o"),
            "--hdri",
            str(tmp_path / "no.exr"),
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert p.returncode == 2 and p.stderr.strip().startswith("ctlab: error: HDRI not found")
    assert not (tmp_path / "o").exists()


def _snapshot():
    return (
        sorted(o.name for o in bpy.data.objects),
        sorted(m.name for m in bpy.data.materials),
        sorted(w.name for w in bpy.data.worlds),
        [(n.name, n.bl_idname) for n in bpy.data.materials["Material"].node_tree.nodes],
    )


@pytest.mark.parametrize("case", OPERATOR_CASES)
def test_operator_bad_input(case, addon, tmp_path, monkeypatch):
    cube = bpy.data.objects["Cube"]
    bpy.context.view_layer.objects.active = cube
    message = {
        "op-matrix-hdri": "HDRI not found: /nonexistent.exr",
        "op-bake-hdri": "HDRI not found: /nonexistent.exr",
        "op-convert-not-principled": "its surface is not a Principled BSDF",
        "op-convert-not-model": "does not use the Cook-Torrance model",
        "op-convert-no-material": "no material to convert",
        "op-comparison-running": "a comparison is already running",
        "op-comparison-out-backslash": "holds a backslash, which Blender reads",
    }[case]
    cache = tmp_path / "cache"
    monkeypatch.setenv("CTLAB_CACHE", str(cache))
    if case == "op-convert-not-principled":
        nt = bpy.data.materials["Material"].node_tree
        emission = nt.nodes.new("ShaderNodeEmission")
        nt.links.new(emission.outputs[0], nt.nodes["Material Output"].inputs["Surface"])
    if case == "op-convert-no-material":
        cube.data.materials.clear()
        bpy.data.materials["Material"].use_fake_user = True
    if case == "op-comparison-running":
        monkeypatch.setitem(
            operators.JOBS,
            "comparison",
            types.SimpleNamespace(poll=lambda: "running", state="running"),
        )
    before = _snapshot()
    call = {
        "op-matrix-hdri": lambda: bpy.ops.ctlab.build_sphere_matrix(hdri="/nonexistent.exr"),
        "op-bake-hdri": lambda: bpy.ops.ctlab.bake_environment(filepath="/nonexistent.exr"),
        "op-convert-not-principled": lambda: bpy.ops.ctlab.convert_to_cook_torrance(),
        "op-convert-not-model": lambda: bpy.ops.ctlab.convert_to_principled(),
        "op-convert-no-material": lambda: bpy.ops.ctlab.convert_to_cook_torrance(),
        "op-comparison-running": lambda: bpy.ops.ctlab.render_comparison(
            directory=str(tmp_path / "out")
        ),
        "op-comparison-out-backslash": lambda: bpy.ops.ctlab.render_comparison(
            directory=str(tmp_path / "out") + "\\sub"
        ),
    }[case]
    with pytest.raises(RuntimeError, match=re.escape(message)):
        call()
    assert _snapshot() == before  # the scene and materials as they were
    assert not cache.exists() or not any(cache.iterdir())
    assert not (tmp_path / "out").exists()
