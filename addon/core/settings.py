"""What a render of the sphere matrix is, as data: the grid, the image, the world, the key
Sun, the model's options and which shader carries it; validated once, with one-line errors.
Also the matrix's geometry (docs/model.md "The sphere matrix"), which both the scene builder
and scene.json use: columns metallic 0 -> 1 left to right, rows smoothness 1 -> 0 top to
bottom, the grid in the XZ plane seen by an orthographic camera looking along +Y."""

from __future__ import annotations

import dataclasses
import json
import math
from dataclasses import dataclass, field

from .errors import UserError
from .lights import PER_TYPE
from .model import BAKED_IBL_MODES, DEFAULT_ALBEDO, LIGHT_SLOTS, SHADERS, ModelOptions

MAX_GRID = 16
SIZE_RANGE = (16, 4096)
MAX_STRENGTH = 1e6  # the node group's inputs' maximum (core.model.LIGHTING)
MIN_SPHERE_PX = 3.0  # a sphere's radius in pixels, so that the comparison has cells
CAMERA_DISTANCE = 20.0
TO_CAMERA = (0.0, -1.0, 0.0)


def with_overrides(s: MatrixSettings, overrides: dict) -> MatrixSettings:
    """New settings with scene fields or model options (``view``, ``g_model``, ...) replaced,
    validated as they are made."""
    model_keys = set(vars(s.model))
    model = ModelOptions(
        **dict(vars(s.model), **{k: v for k, v in overrides.items() if k in model_keys})
    )
    scene = {k: v for k, v in overrides.items() if k not in model_keys}
    return dataclasses.replace(s, model=model, **scene)


def matrix_values(rows: int, cols: int):
    """(row, col, metallic, smoothness) of each sphere: metallic 0 -> 1 by column, smoothness
    1 -> 0 by row (0.5 for a single row or column)."""
    for r in range(rows):
        smooth = 1.0 - r / (rows - 1) if rows > 1 else 0.5
        for c in range(cols):
            metal = c / (cols - 1) if cols > 1 else 0.5
            yield r, c, metal, smooth


def normalized(v) -> tuple:
    length = math.hypot(*v)  # no overflow for huge components
    return tuple(x / length for x in v)


def _finite32(x) -> bool:
    """Finite as a float32 (what Blender stores): 1e39 is not."""
    try:
        return math.isfinite(x) and abs(x) <= 3.4028234663852886e38
    except TypeError:
        return False


@dataclass
class MatrixSettings:
    rows: int = 7
    cols: int = 7
    spacing: float = 1.0  # distance between sphere centres (m)
    radius: float = 0.42  # sphere radius (m)
    albedo: tuple = DEFAULT_ALBEDO
    hdri: str = ""  # empty: Blender's bundled forest.exr
    hdri_strength: float = 1.0
    hdri_rotation: float = 0.0  # radians about Z, as the Mapping node (degrees only
    # at the boundary: --hdri-rotation, scene.json)
    sun_to_light: tuple = (-0.45, -0.55, 0.70)
    sun_strength: float = 1.0  # irradiance (W/m^2), Blender's Sun strength
    sun_color: tuple = (1.0, 1.0, 1.0)
    shader: str = "osl"
    principled_distribution: str = "MULTI_GGX"
    width: int = 512
    height: int = 512
    model: ModelOptions = field(default_factory=ModelOptions)
    metallic: float | None = None  # every sphere's metallic (None: 0 -> 1 by column)
    # Spheres shadow each other (the Sun's and, in a path tracer, the world's light); off,
    # each sphere is lit by the unoccluded world, as the model's integrator assumes.
    mutual_shadows: bool = True
    # Scene lights (core.lights.Light, at most LIGHT_SLOTS) in place of the key Sun
    lights: tuple = ()
    lights_file: str = ""  # where they were read from (for scene.json)
    # The seed's textures on every sphere (core/textures.py): an albedo texture in place of
    # ``albedo``, a tangent-space normal map (OpenGL convention) and its strength
    albedo_texture: str = ""
    normal_map: str = ""
    normal_strength: float = 1.0

    def __post_init__(self):
        self.validate()  # settings are checked once, when made

    def cells(self):
        """(row, col, metallic, smoothness) of every sphere."""
        for row, col, metal, smooth in matrix_values(self.rows, self.cols):
            yield row, col, (metal if self.metallic is None else self.metallic), smooth

    def model_options(self, **changes) -> ModelOptions:
        """The model's options for this scene: it traces shadow rays exactly when the spheres
        shadow each other (as Principled's do; being convex, none shadows itself)."""
        return ModelOptions(**dict(vars(self.model), shadow_rays=self.mutual_shadows, **changes))

    def to_light(self) -> tuple:
        return normalized(self.sun_to_light)

    def irradiance(self) -> tuple:
        return tuple(self.sun_strength * c for c in self.sun_color)

    def validate(self) -> None:
        if not (1 <= self.rows <= MAX_GRID and 1 <= self.cols <= MAX_GRID):
            raise UserError(
                f"grid {self.rows}x{self.cols} out of range; use 1x1 to {MAX_GRID}x{MAX_GRID}"
            )
        for n in (self.width, self.height):
            if not SIZE_RANGE[0] <= n <= SIZE_RANGE[1]:
                raise UserError(
                    f"image size {n} out of range; use {SIZE_RANGE[0]} to {SIZE_RANGE[1]}"
                )
        if self.shader not in SHADERS:
            raise UserError(f"unknown shader {self.shader!r}; choose one of: {', '.join(SHADERS)}")
        if self.shader == "nodes" and self.model.ibl not in BAKED_IBL_MODES:
            raise UserError(
                f"the node group has no {self.model.ibl!r} indirect light (it "
                "cannot integrate an HDRI); use one of: " + ", ".join(BAKED_IBL_MODES)
            )
        vec = tuple(self.sun_to_light)
        if len(vec) != 3 or not all(_finite32(x) for x in vec) or math.hypot(*vec) < 1e-6:
            raise UserError(f"sun direction {vec} is not a non-zero 3-vector")
        for name in ("hdri_strength", "sun_strength"):
            value = getattr(self, name)
            if not (_finite32(value) and 0 <= value <= MAX_STRENGTH):
                raise UserError(
                    f"{name.replace('_', ' ')} {value} out of range; use 0 to {MAX_STRENGTH:g}"
                )
        if not _finite32(self.hdri_rotation):
            raise UserError(
                f"hdri rotation {self.hdri_rotation} out of range; use a finite number of radians"
            )
        radius_px = self.radius * world_to_pixel(self, (0.0, 0.0, 0.0))[1]
        if radius_px < MIN_SPHERE_PX:
            need = math.ceil(MIN_SPHERE_PX * self.width / radius_px)
            raise UserError(
                f"image size {self.width} is too small for a {self.rows}x{self.cols} "
                f"grid (spheres {radius_px:.1f} px across their radius); use "
                f"--size {min(need, SIZE_RANGE[1])} or a smaller grid"
            )
        if self.metallic is not None and not 0.0 <= self.metallic <= 1.0:
            raise UserError(f"metallic {self.metallic} out of range; use 0 to 1")
        if len(self.albedo) != 3 or not all(0.0 <= a <= 1.0 for a in self.albedo):
            raise UserError(f"albedo {self.albedo} out of range; use three values in [0, 1]")
        if not (_finite32(self.normal_strength) and 0.0 <= self.normal_strength <= 10.0):
            raise UserError(
                f"normal strength {self.normal_strength} out of range; use 0 to 10 (Blender's "
                "Normal Map node)"
            )
        if len(self.lights) > LIGHT_SLOTS:
            raise UserError(f"{len(self.lights)} lights; the model shades at most {LIGHT_SLOTS}")
        self.model.validate()


# ----------------------------------------------------------------------------------------
# Geometry of the grid (the camera framing and the cells' pixel positions come from here)


def cell_center(s: MatrixSettings, row: int, col: int) -> tuple:
    """World position of a sphere: the grid lies in the XZ plane, the camera looks along +Y."""
    return ((col - (s.cols - 1) / 2) * s.spacing, 0.0, ((s.rows - 1) / 2 - row) * s.spacing)


def ortho_scale(s: MatrixSettings) -> float:
    """Blender's orthographic scale spans the larger image dimension (sensor fit AUTO)."""
    aspect = s.width / s.height
    return (
        max(s.cols * s.spacing, s.rows * s.spacing * aspect)
        if aspect >= 1
        else max(s.rows * s.spacing, s.cols * s.spacing / aspect)
    )


def world_to_pixel(s: MatrixSettings, p) -> tuple:
    """Pixel coordinates (origin top-left, x right, y down) of a world point in the XZ plane,
    and the pixels per metre."""
    px_per_m = max(s.width, s.height) / ortho_scale(s)
    return (s.width / 2 + p[0] * px_per_m, s.height / 2 - p[2] * px_per_m), px_per_m


def describe(s: MatrixSettings, hdri: str) -> dict:
    """The scene as data for scene.json: image size, directions, and each cell in pixels
    (``hdri``: the file the world shows)."""
    cells = []
    for row, col, metal, smooth in s.cells():
        (cx, cy), px_per_m = world_to_pixel(s, cell_center(s, row, col))
        cells.append(
            {
                "row": row,
                "col": col,
                "metallic": metal,
                "smoothness": smooth,
                "albedo": list(s.albedo),
                "center_px": [cx, cy],
                "radius_px": s.radius * px_per_m,
            }
        )
    return {
        "width": s.width,
        "height": s.height,
        "to_camera": list(TO_CAMERA),
        "sun": {
            "to_light": list(s.to_light()),
            "irradiance": [0.0] * 3 if s.lights else list(s.irradiance()),
        },
        "lights": [light_record(light) for light in s.lights],
        "lights_file": s.lights_file,
        "hdri": str(hdri),
        "hdri_strength": s.hdri_strength,
        "hdri_rotation_deg": math.degrees(s.hdri_rotation),
        "shader": s.shader,
        "principled_distribution": s.principled_distribution,
        "textures": {
            "albedo_texture": s.albedo_texture,
            "normal_map": s.normal_map,
            "normal_strength": s.normal_strength,
        },
        "rows": s.rows,
        "cols": s.cols,
        "model": s.model.as_dict(),
        "cells": cells,
    }


def light_record(light) -> dict:
    """A light as scene.json records it (Blender's property names, as a --lights file)."""
    record = {
        "type": light.type,
        "name": light.name,
        "location": list(light.location),
        "rotation_euler": list(light.rotation_euler),
        "scale": list(light.scale),
        "color": list(light.color),
        "energy": light.energy,
        "exposure": light.exposure,
        "use_shadow": light.use_shadow,
    }
    record.update({k: light.get(k) for k in PER_TYPE[light.type]})
    return record


# ----------------------------------------------------------------------------------------
# Settings as data (a job plan stores them: core/jobgraph/plan.py)

_TUPLE_FIELDS = ("albedo", "sun_to_light", "sun_color")
_LIGHT_TUPLES = ("location", "rotation_euler", "scale", "color")


def settings_to_dict(s: MatrixSettings) -> dict:
    """The settings as plain JSON data (settings_from_dict reads them back, validated)."""
    data = {f.name: getattr(s, f.name) for f in dataclasses.fields(s)}
    data["model"] = dict(vars(s.model))
    data["lights"] = [dataclasses.asdict(light) for light in s.lights]
    return json.loads(json.dumps(data))


def settings_from_dict(data: dict) -> MatrixSettings:
    """Settings written by settings_to_dict; a field this version does not know, or a bad
    value, is a UserError naming it."""
    from .lights import Light

    try:
        d = dict(data)
        model = ModelOptions(**d.pop("model"))
        lights = tuple(
            Light(**dict(light, **{k: tuple(light[k]) for k in _LIGHT_TUPLES if k in light}))
            for light in d.pop("lights", ())
        )
        d.update({k: tuple(d[k]) for k in _TUPLE_FIELDS if k in d})
        return MatrixSettings(model=model, lights=lights, **d)
    except (TypeError, KeyError, AttributeError) as exc:
        raise UserError(
            f"settings written by another version of ctlab ({exc}); plan the job again"
        ) from None
