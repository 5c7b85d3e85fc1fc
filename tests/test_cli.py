"""The command line: scene.json, the main job end to end, and bad input (one line, exit 2,
nothing written)."""

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from conftest import ROOT

CTLAB = [sys.executable, str(ROOT / "scripts" / "ctlab.py")]


def run(*args, cwd=None):
    return subprocess.run(CTLAB + [str(a) for a in args], capture_output=True, text=True,
                          cwd=cwd, env=dict(os.environ), timeout=300)


def test_render_writes_exr_png_and_scene_json(tmp_path):
    out = tmp_path / "r"
    p = run("render", "--shader", "osl", "--out", out, "--view", "NdotV", "--grid", "2x3",
            "--size", "60", "--sun-dir", "1,-1,1")
    assert p.returncode == 0, p.stderr
    assert sorted(x.name for x in out.iterdir()) == ["render.exr", "render.png", "scene.json"]
    scene = json.loads((out / "scene.json").read_text())
    assert scene["width"] == scene["height"] == 60
    assert np.allclose(scene["sun"]["to_light"], np.array([1, -1, 1]) / np.sqrt(3))
    assert len(scene["cells"]) == 6
    cell = next(c for c in scene["cells"] if c["row"] == 1 and c["col"] == 2)
    assert cell["metallic"] == 1.0 and cell["smoothness"] == 0.0
    # the NdotV view peaks (= 1) at each sphere's centre pixel, where the normal faces the camera
    from addon.compare import read_image
    img = read_image(out / "render.exr")
    for c in scene["cells"]:
        x, y = (int(v) for v in c["center_px"])
        assert img[y, x, 0] > 0.99
    assert img[0, 0, 0] != pytest.approx(1.0, abs=0.01)                  # a corner: the world


def test_matrix_main_job_writes_a_report(tmp_path):
    out = tmp_path / "m"
    p = run("matrix", "--out", out, "--grid", "2x2", "--size", "48", "--samples", "4")
    assert p.returncode == 0, p.stderr + p.stdout
    assert "[1/7]" in p.stdout and "[7/7]" in p.stdout
    for f in ("report.html", "cook_torrance/render.png", "principled/render.png",
              "compare/diff.png", "compare/metrics.json"):
        assert (out / f).is_file(), f
    metrics = json.loads((out / "compare" / "metrics.json").read_text())
    assert len(metrics["cells"]) == 4
    for key in ("mae", "rmse", "psnr_db", "ciede2000_mean"):
        assert np.isfinite(metrics["overall"][key])
    html = (out / "report.html").read_text()
    assert "cook_torrance/render.png" in html and "compare/diff.png" in html
    for study in ("split_sum", "unity", "nodes"):
        assert f"{study}/render.png" in html and f"compare_{study}/diff.png" in html
        cells = json.loads((out / f"compare_{study}" / "metrics.json").read_text())["cells"]
        assert all(np.isfinite(c["rel_luminance_error"]) for c in cells)
    assert not list(out.rglob("*partial*"))


def _non_float_image(tmp_path):
    import bpy  # noqa: F401
    from addon.compare import write_png
    path = tmp_path / "ldr.png"
    write_png(path, np.zeros((16, 32, 3)))
    return path


BAD = {
    "missing hdri": (["--hdri", "/nonexistent/sky.exr"], "HDRI not found"),
    "non-float hdri": (["--hdri", "@LDR"], "not floating point"),
    "malformed vector": (["--sun-dir", "1,2"], "malformed sun direction"),
    "unknown view": (["--view", "Q"], "unknown view"),
    "grid out of range": (["--grid", "40x2"], "grid 40x2 out of range"),
    "size out of range": (["--size", "5"], "image size 5 out of range"),
    "unwritable output": (["--out", "@FILE/sub"], "output folder not writable"),
    "bad samples": (["--samples", "0"], "samples 0 out of range"),
    "unknown ibl": (["--ibl", "probe"], "unknown IBL 'probe'"),
    "eevee with osl": (["--engine", "eevee"], "--engine eevee renders the node group only"),
}


@pytest.mark.parametrize("case", list(BAD))
def test_bad_input_one_line_exit_2_nothing_written(tmp_path, case):
    extra, message = BAD[case]
    blocker = tmp_path / "a-file"
    blocker.write_text("x")
    extra = [str(_non_float_image(tmp_path)) if a == "@LDR" else
             a.replace("@FILE", str(blocker)) for a in extra]
    out = tmp_path / "out"
    args = ["render", "--shader", "osl", "--size", "32", "--grid", "1x1"]
    if "--out" not in extra:
        args += ["--out", out]
    p = run(*args, *extra)
    assert p.returncode == 2, p.stderr
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1 and message in lines[0], p.stderr
    assert not out.exists()


def test_compare_rejects_a_folder_without_a_render(tmp_path):
    p = run("compare", tmp_path, tmp_path, "--out", tmp_path / "c")
    assert p.returncode == 2 and "not a render folder" in p.stderr
    assert not (tmp_path / "c").exists()
