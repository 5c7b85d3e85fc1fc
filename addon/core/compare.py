"""Comparing two renders of the same scene: per-cell and overall metrics, a difference map.

Metrics (per cell over the pixels inside 0.95 of the sphere radius, and over all cells):
- MAE and RMSE of the raw float values (render.exr, RGB);
- the relative luminance error of the cell's mean: (Y_a - Y_b) / Y_b, Y = Rec. 709 luminance
  of the raw values (signed: positive where A is brighter);
- PSNR of the displayed colours (render.png, 0..1, peak 1);
- mean CIEDE2000 of the displayed colours (sRGB -> CIE Lab, D65), after Sharma, Wu & Dalal,
  "The CIEDE2000 color-difference formula: implementation notes", 2005.

And per material of a user's scene (``ctlab scene``): the Material Index pass read from a
multilayer EXR, the same metrics and the luminance ratio over each material's mask, the noise
floor and the CIEDE2000 of the mean colour, the map of the masks (materials.png).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from .errors import UserError
from .files import (
    atomic_path,
    atomic_paths,
    check_writable,
    finite_json,
    json_text,
    refuse_overwrite,
)
from .hdri import oiio, read_pixels
from .model import REC709_LUMINANCE

CELL_FRACTION = 0.95


def read_image(path: Path) -> np.ndarray:
    """An image as float32 (h, w, 3), read whole (hdri.read_pixels)."""
    return read_pixels(path, "image")


def write_png(path: Path, rgb01: np.ndarray) -> None:
    """Write an 8-bit RGB PNG (values already display-referred in 0..1), whole or not at all."""
    with atomic_path(path) as tmp:
        write_png_to(tmp, rgb01, path)


def write_png_to(tmp: Path, rgb01: np.ndarray, final: Path) -> None:
    """write_png's writer, into a path already staged (core.files.atomic_paths) for
    ``final``."""
    OIIO = oiio()
    h, w, _ = rgb01.shape
    buf = OIIO.ImageBuf(OIIO.ImageSpec(w, h, 3, OIIO.UINT8))
    buf.set_pixels(OIIO.ROI(0, w, 0, h, 0, 1, 0, 3), np.clip(rgb01, 0, 1).astype(np.float32))
    if not buf.write(str(tmp)):
        raise UserError(f"cannot write {final}: {' '.join(buf.geterror().split())}")


# --- Colour science -------------------------------------------------------------------


def srgb_to_linear(c: np.ndarray) -> np.ndarray:
    c = np.asarray(c, dtype=np.float64)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


_SRGB_TO_XYZ = np.array(
    [
        [0.4124564, 0.3575761, 0.1804375],
        [0.2126729, 0.7151522, 0.0721750],
        [0.0193339, 0.1191920, 0.9503041],
    ]
)
_WHITE_D65 = np.array([0.95047, 1.0, 1.08883])


def srgb_to_lab(c: np.ndarray) -> np.ndarray:
    """Display sRGB (0..1) to CIE L*a*b* (D65)."""
    xyz = srgb_to_linear(c) @ _SRGB_TO_XYZ.T / _WHITE_D65
    eps, kappa = 216 / 24389, 24389 / 27
    f = np.where(xyz > eps, np.cbrt(xyz), (kappa * xyz + 16) / 116)
    return np.stack(
        [116 * f[..., 1] - 16, 500 * (f[..., 0] - f[..., 1]), 200 * (f[..., 1] - f[..., 2])],
        axis=-1,
    )


HUE_EPS = 1e-9  # degrees: hue differences this close to 180 count as 180


def ciede2000(lab1: np.ndarray, lab2: np.ndarray) -> np.ndarray:
    """CIEDE2000 colour difference (kL = kC = kH = 1), Sharma et al. 2005, eqs. 1-22."""
    L1, a1, b1 = np.moveaxis(np.asarray(lab1, dtype=np.float64), -1, 0)
    L2, a2, b2 = np.moveaxis(np.asarray(lab2, dtype=np.float64), -1, 0)
    C1, C2 = np.hypot(a1, b1), np.hypot(a2, b2)
    Cbar = (C1 + C2) / 2
    G = 0.5 * (1 - np.sqrt(Cbar**7 / (Cbar**7 + 25.0**7)))
    a1p, a2p = (1 + G) * a1, (1 + G) * a2
    C1p, C2p = np.hypot(a1p, b1), np.hypot(a2p, b2)
    h1p = np.degrees(np.arctan2(b1, a1p)) % 360
    h2p = np.degrees(np.arctan2(b2, a2p)) % 360
    dLp = L2 - L1
    dCp = C2p - C1p
    # Hues exactly opposite (|h1' - h2'| = 180 in exact arithmetic: Sharma's pair 14) sit on a
    # discontinuity of the mean hue; round-off must not pick the other side (numpy 1.26's
    # degrees/arctan2 put it at 180 + 3e-14 and gave 4.7461 for the published 4.8045).
    dhp = h2p - h1p
    beyond = np.abs(dhp) > 180 + HUE_EPS
    dhp = np.where(beyond, dhp - 360 * np.sign(dhp), dhp)
    dhp = np.where(C1p * C2p == 0, 0.0, dhp)
    dHp = 2 * np.sqrt(C1p * C2p) * np.sin(np.radians(dhp) / 2)
    Lbp = (L1 + L2) / 2
    Cbp = (C1p + C2p) / 2
    hsum = h1p + h2p
    hbp = np.where(beyond, np.where(hsum < 360, (hsum + 360) / 2, (hsum - 360) / 2), hsum / 2)
    hbp = np.where(C1p * C2p == 0, hsum, hbp)
    T = (
        1
        - 0.17 * np.cos(np.radians(hbp - 30))
        + 0.24 * np.cos(np.radians(2 * hbp))
        + 0.32 * np.cos(np.radians(3 * hbp + 6))
        - 0.20 * np.cos(np.radians(4 * hbp - 63))
    )
    dtheta = 30 * np.exp(-(((hbp - 275) / 25) ** 2))
    Rc = 2 * np.sqrt(Cbp**7 / (Cbp**7 + 25.0**7))
    Sl = 1 + 0.015 * (Lbp - 50) ** 2 / np.sqrt(20 + (Lbp - 50) ** 2)
    Sc = 1 + 0.045 * Cbp
    Sh = 1 + 0.015 * Cbp * T
    Rt = -np.sin(np.radians(2 * dtheta)) * Rc
    return np.sqrt(
        (dLp / Sl) ** 2 + (dCp / Sc) ** 2 + (dHp / Sh) ** 2 + Rt * (dCp / Sc) * (dHp / Sh)
    )


# --- Masks and metrics ------------------------------------------------------------------


def cell_mask(shape, cell: dict, fraction: float = CELL_FRACTION) -> np.ndarray:
    """Pixels whose centres lie within fraction x radius of the sphere's centre."""
    h, w = shape[:2]
    ys, xs = np.mgrid[0:h, 0:w]
    cx, cy = cell["center_px"]
    return (xs + 0.5 - cx) ** 2 + (ys + 0.5 - cy) ** 2 <= (fraction * cell["radius_px"]) ** 2


def metrics(lin_a, lin_b, disp_a, disp_b, de, mask) -> dict:
    d = (lin_a[mask] - lin_b[mask]).astype(np.float64)
    mse_disp = float(np.mean((disp_a[mask].astype(np.float64) - disp_b[mask]) ** 2))
    y_a = float(np.mean(lin_a[mask] @ np.array(REC709_LUMINANCE)))
    y_b = float(np.mean(lin_b[mask] @ np.array(REC709_LUMINANCE)))
    return {
        "pixels": int(mask.sum()),
        "mae": float(np.mean(np.abs(d))),
        "rmse": float(np.sqrt(np.mean(d**2))),
        "rel_luminance_error": (y_a - y_b) / y_b if y_b > 0 else None,
        "psnr_db": float(10 * math.log10(1.0 / mse_disp)) if mse_disp > 0 else float("inf"),
        "ciede2000_mean": float(np.mean(de[mask])),
        "ciede2000_p95": float(np.percentile(de[mask], 95)),
    }


def heatmap(de: np.ndarray, vmax: float = 10.0) -> np.ndarray:
    """CIEDE2000 per pixel as colour: black (0) -> blue -> red -> yellow -> white (>= vmax)."""
    stops = np.array([[0, 0, 0], [0.1, 0.2, 0.8], [0.85, 0.1, 0.1], [1, 0.85, 0], [1, 1, 1]])
    x = np.clip(de / vmax, 0, 1) * (len(stops) - 1)
    i = np.minimum(x.astype(int), len(stops) - 2)
    f = (x - i)[..., None]
    return stops[i] * (1 - f) + stops[i + 1] * f


RENDER_FILES = ("render.exr", "render.png", "scene.json")


def _scene_problem(scene) -> str | None:
    """What is wrong with a scene.json's content, or None (the keys compare reads)."""

    def number(x):
        return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)

    if not isinstance(scene, dict):
        return "it is not a JSON object"
    for key in ("width", "height"):
        if not (isinstance(scene.get(key), int) and 0 < scene[key] <= 65536):
            return f"'{key}' is not a positive image size"
    cells = scene.get("cells")
    if not isinstance(cells, list) or not cells:
        return "'cells' is not a non-empty list"
    for i, c in enumerate(cells):
        if not isinstance(c, dict):
            return f"cell {i} is not an object"
        for key in ("row", "col"):
            if not isinstance(c.get(key), int):
                return f"cell {i} has no integer '{key}'"
        for key in ("metallic", "smoothness", "radius_px"):
            if not number(c.get(key)):
                return f"cell {i} has no finite '{key}'"
        centre = c.get("center_px")
        if not (isinstance(centre, list) and len(centre) == 2 and all(map(number, centre))):
            return f"cell {i} has no 'center_px' [x, y]"
    return None


def load_render(folder: Path):
    """A render folder's images and scene, each checked: the three files there, scene.json
    well-formed, both images whole, of the scene's size and free of NaN/Inf."""
    folder = Path(folder)
    for name in RENDER_FILES:
        if not (folder / name).is_file():
            raise UserError(
                f"{folder} is not a render folder: {name} is missing (make it with 'ctlab render')"
            )
    try:
        scene = json.loads((folder / "scene.json").read_text(encoding="utf-8"))
    except (ValueError, UnicodeDecodeError) as exc:
        raise UserError(
            f"{folder / 'scene.json'} is not valid JSON ({exc}); render the folder again"
        ) from None
    problem = _scene_problem(scene)
    if problem:
        raise UserError(f"{folder / 'scene.json'} is not a render's description: {problem}")
    images = []
    for name in ("render.exr", "render.png"):
        img = read_image(folder / name)
        if img.shape[:2] != (scene["height"], scene["width"]):
            raise UserError(
                f"{folder / name} is {img.shape[1]}x{img.shape[0]}, but scene.json "
                f"says {scene['width']}x{scene['height']}; render the folder again"
            )
        bad = int((~np.isfinite(img)).any(axis=2).sum())
        if bad:
            raise UserError(f"{folder / name} holds {bad} NaN/Inf pixel(s); it cannot be compared")
        images.append(img)
    return images[0], images[1], scene


def compare(dir_a: Path, dir_b: Path, out_dir: Path) -> dict:
    """Write metrics.json and diff.png (CIEDE2000 heat map) into out_dir; return the metrics."""
    lin_a, disp_a, scene_a = load_render(dir_a)
    lin_b, disp_b, scene_b = load_render(dir_b)
    if lin_a.shape != lin_b.shape:
        raise UserError(
            f"renders differ in size: {lin_a.shape[1]}x{lin_a.shape[0]} vs "
            f"{lin_b.shape[1]}x{lin_b.shape[0]}; render both with the same --size"
        )
    cells_a = [(c["row"], c["col"]) for c in scene_a["cells"]]
    if cells_a != [(c["row"], c["col"]) for c in scene_b["cells"]]:
        raise UserError("renders have different sphere grids; render both with the same --grid")
    masks = [cell_mask(lin_a.shape, cell) for cell in scene_a["cells"]]
    for cell, mask in zip(scene_a["cells"], masks):
        if not mask.any():
            raise UserError(
                f"sphere {cell['row']},{cell['col']} of {dir_a} covers no pixel; "
                "render with a larger --size or a smaller --grid"
            )
    refuse_overwrite(
        [Path(d) / n for d in (dir_a, dir_b) for n in RENDER_FILES],
        [Path(out_dir) / "metrics.json", Path(out_dir) / "diff.png"],
        [out_dir],
    )
    out_dir = check_writable(out_dir)
    de = ciede2000(srgb_to_lab(disp_a), srgb_to_lab(disp_b))
    all_mask = np.logical_or.reduce(masks)
    cells = [
        {k: cell[k] for k in ("row", "col", "metallic", "smoothness")}
        | metrics(lin_a, lin_b, disp_a, disp_b, de, mask)
        for cell, mask in zip(scene_a["cells"], masks)
    ]
    result = {
        "a": str(dir_a),
        "b": str(dir_b),
        "a_shader": scene_a.get("shader"),
        "b_shader": scene_b.get("shader"),
        "overall": metrics(lin_a, lin_b, disp_a, disp_b, de, all_mask),
        "heatmap_max_ciede2000": 10.0,
        "cells": cells,
    }
    result = finite_json(result)  # standard JSON: an infinite PSNR (identical) is null
    # both files or neither (a failed write of one keeps the other out too)
    with atomic_paths(out_dir / "diff.png", out_dir / "metrics.json") as (png, js):
        write_png_to(png, heatmap(de), out_dir / "diff.png")
        js.write_text(json_text(result), encoding="utf-8")
    return result


# --- Per material of a user's scene (``ctlab scene``) ---------------------------------

# Colours of the compared materials in materials.png (others grey, the world black).
PALETTE = (
    (0.90, 0.30, 0.25),
    (0.25, 0.60, 0.95),
    (0.35, 0.80, 0.35),
    (0.95, 0.75, 0.20),
    (0.70, 0.40, 0.85),
    (0.20, 0.80, 0.80),
    (0.95, 0.50, 0.70),
    (0.60, 0.45, 0.25),
)
OTHER_GREY = 0.35
INDEX_CHANNELS = ("IndexMA.X", "Material Index.X")  # 4.5; 5.x


def read_material_index(path: Path) -> np.ndarray:
    """The Material Index pass of a multilayer EXR (all parts searched) as int (h, w)."""
    OIIO = oiio()
    inp = OIIO.ImageInput.open(str(path))
    if inp is None:
        raise UserError(f"cannot read {path}: {OIIO.geterror().strip()}")
    try:
        part = 0
        while inp.seek_subimage(part, 0):
            spec = inp.spec()
            for c, name in enumerate(spec.channelnames):
                if any(name == ch or name.endswith("." + ch) for ch in INDEX_CHANNELS):
                    px = inp.read_image(part, 0, c, c + 1, OIIO.FLOAT)
                    px = np.asarray(px, dtype=np.float32).reshape(spec.height, spec.width)
                    return np.rint(px).astype(np.int32)
            part += 1
    finally:
        inp.close()
    raise UserError(f"{path} holds no Material Index pass; Blender did not render it")


def _luminance(img: np.ndarray, mask: np.ndarray):
    if not mask.any():
        return None
    return float(np.mean(img[mask].astype(np.float64) @ np.array(REC709_LUMINANCE)))


def measure(lin_m, disp_m, lin_p, disp_p, de, mask) -> dict:
    """compare.metrics (model as A, Principled as B) and the luminance ratio model/Principled
    over a mask; None where the mask is empty."""
    y_m, y_p = _luminance(lin_m, mask), _luminance(lin_p, mask)
    out = {
        "pixels": int(mask.sum()),
        "luminance_model": y_m,
        "luminance_principled": y_p,
        "luminance_ratio": (y_m / y_p) if y_m is not None and y_p else None,
    }
    if mask.any():
        out.update(metrics(lin_m, lin_p, disp_m, disp_p, de, mask))
    else:
        out.update(
            {
                k: None
                for k in (
                    "mae",
                    "rmse",
                    "rel_luminance_error",
                    "psnr_db",
                    "ciede2000_mean",
                    "ciede2000_p95",
                )
            }
        )
    return out


def what_numbers_mean(lin_p, lin_p2, disp_m, disp_p, de_noise, mask) -> dict:
    """Beside the per-pixel mean CIEDE2000, what a reader needs to weigh it: the noise floor,
    the same measures between Principled and Principled rendered again with another seed
    (the same scene, so all of it is Monte Carlo noise), and the CIEDE2000 of the mask's
    mean displayed colours, model against Principled (noise averages out of a mean, not out
    of the per-pixel mean: a pixel's noise adds to its difference)."""
    if not mask.any():
        return dict.fromkeys(
            ("noise_floor_ciede2000_mean", "noise_floor_luminance_ratio", "ciede2000_of_mean")
        )
    mean_m, mean_p = (np.mean(d[mask][:, :3].astype(np.float64), axis=0) for d in (disp_m, disp_p))
    y_p, y_p2 = _luminance(lin_p, mask), _luminance(lin_p2, mask)
    lab_m, lab_p = (srgb_to_lab(c.reshape(1, 1, 3)) for c in (mean_m, mean_p))
    return {
        "noise_floor_ciede2000_mean": float(np.mean(de_noise[mask])),
        "noise_floor_luminance_ratio": (y_p2 / y_p) if y_p else None,
        "ciede2000_of_mean": float(ciede2000(lab_m, lab_p).ravel()[0]),
    }


def mask_image(index: np.ndarray, entries: list) -> np.ndarray:
    """materials.png: each compared material in its palette colour, other materials grey,
    the world (index 0) black."""
    img = np.where((index > 0)[..., None], OTHER_GREY, 0.0) * np.ones(3)
    for e in entries:
        img[index == e["pass_index"]] = e["mask_colour"]
    return img
