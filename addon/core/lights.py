"""Scene lights for the model, in Blender's own terms (docs/model.md "Lights"): a light as
Blender describes it (type, object transform, colour, power and shape), read from a
``--lights`` file and checked, and the model's slot inputs that stand for it.

The slot inputs (core.model LIGHTS) are world-space values that both implementations shade
with Cycles' conventions: Color = colour x power x 2^exposure (W; a Sun's strength in W/m^2),
Direction = the object's -Z axis, Axis X / Y = half the Area light's size along its X / Y axes
(object scale included), Size = a Point or Spot's radius or a Sun's angle. Blender's drivers
compute the same values from light objects (blender/drivers.py), so this module is also the
independent reference that a test holds the drivers to.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path

from .errors import UserError
from .model import LIGHT_SLOTS, LIGHT_TYPE_CODES

TYPES = ("SUN", "POINT", "SPOT", "AREA")
SHAPES = ("SQUARE", "RECTANGLE", "DISK", "ELLIPSE")
MAX_VALUE = 1e6  # the largest distance, size or power a file may give
MAX_POWER = 1e9  # the largest colour x energy x 2^exposure (the slot's Color input)

# The keys a light of each type takes (Blender's property names), with
# bpy.data.lights.new()'s defaults; energy is required.
COMMON = {
    "type": None,
    "name": "",
    "location": (0.0, 0.0, 0.0),
    "rotation_euler": (0.0, 0.0, 0.0),
    "scale": (1.0, 1.0, 1.0),
    "color": (1.0, 1.0, 1.0),
    "energy": None,
    "exposure": 0.0,
    "use_shadow": True,
}
PER_TYPE = {
    "SUN": {"angle": 0.00918043},
    "POINT": {"shadow_soft_size": 0.0},
    "SPOT": {"shadow_soft_size": 0.0, "spot_size": math.radians(45.0), "spot_blend": 0.15},
    "AREA": {"shape": "SQUARE", "size": 0.25, "size_y": 0.25},
}


@dataclass(frozen=True)
class Light:
    """One light, with Blender's property names and units (energy in W, a Sun's in W/m^2;
    angles in radians; ``rotation_euler`` in XYZ order; the light shines along its -Z)."""

    type: str
    energy: float
    name: str = ""
    location: tuple = (0.0, 0.0, 0.0)
    rotation_euler: tuple = (0.0, 0.0, 0.0)
    scale: tuple = (1.0, 1.0, 1.0)
    color: tuple = (1.0, 1.0, 1.0)
    exposure: float = 0.0
    use_shadow: bool = True
    extra: dict = field(default_factory=dict)  # the type's own keys (PER_TYPE)

    def get(self, key):
        return self.extra.get(key, PER_TYPE[self.type].get(key))

    def power(self) -> tuple:
        """colour x energy x 2^exposure, per channel."""
        k = self.energy * 2.0**self.exposure
        return tuple(c * k for c in self.color)


# --- Geometry ---------------------------------------------------------------------------


def euler_matrix(rx: float, ry: float, rz: float) -> tuple:
    """Blender's XYZ Euler rotation, R = Rz Ry Rx, as rows."""
    cx, sx, cy, sy, cz, sz = (
        math.cos(rx),
        math.sin(rx),
        math.cos(ry),
        math.sin(ry),
        math.cos(rz),
        math.sin(rz),
    )
    return (
        (cz * cy, cz * sy * sx - sz * cx, cz * sy * cx + sz * sx),
        (sz * cy, sz * sy * sx + cz * cx, sz * sy * cx - cz * sx),
        (-sy, cy * sx, cy * cx),
    )


def _column(m, j, k=1.0):
    return tuple(m[i][j] * k for i in range(3))


def type_code(light: Light) -> int:
    if light.type == "AREA":
        shape = light.get("shape")
        return LIGHT_TYPE_CODES[
            "AREA_ELLIPSE" if shape in ("DISK", "ELLIPSE") else "AREA_RECTANGLE"
        ]
    return LIGHT_TYPE_CODES[light.type]


def area_size(light: Light) -> tuple:
    """An Area light's full width and height (m), object scale included."""
    shape = light.get("shape")
    w = light.get("size")
    h = light.get("size_y") if shape in ("RECTANGLE", "ELLIPSE") else w
    return abs(w * light.scale[0]), abs(h * light.scale[1])


def slot_values(light: Light) -> dict:
    """The model's slot inputs for ``light`` (field -> value; core.model LIGHT_FIELDS)."""
    m = euler_matrix(*light.rotation_euler)
    values = {
        "type": type_code(light),
        "position": tuple(map(float, light.location)),
        "direction": _column(m, 2, -1.0),
        "axis_x": (0.0, 0.0, 0.0),
        "axis_y": (0.0, 0.0, 0.0),
        "color": light.power(),
        "size": 0.0,
        "spot_size": math.pi,
        "spot_blend": 0.0,
        "shadow": int(bool(light.use_shadow)),
    }
    if light.type == "SUN":
        values["size"] = light.get("angle")
    elif light.type in ("POINT", "SPOT"):
        values["size"] = light.get("shadow_soft_size")
    if light.type == "SPOT":
        values["spot_size"] = light.get("spot_size")
        values["spot_blend"] = light.get("spot_blend")
    if light.type == "AREA":
        w, h = area_size(light)
        sx = math.copysign(1.0, light.scale[0])
        sy = math.copysign(1.0, light.scale[1])
        values["axis_x"] = _column(m, 0, 0.5 * w * sx)
        values["axis_y"] = _column(m, 1, 0.5 * h * sy)
    return values


# --- Reading a --lights file ------------------------------------------------------------


def _number(where, key, value, lo=-MAX_VALUE, hi=MAX_VALUE) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise UserError(f"{where}: {key} must be a number, not {json.dumps(value)[:40]}")
    try:
        value = float(value)  # a JSON integer of 400 digits overflows here
    except OverflowError:
        raise UserError(f"{where}: {key} out of range; use {lo:g} to {hi:g}") from None
    if not math.isfinite(value):
        raise UserError(f"{where}: {key} must be finite, not {value}")
    if not lo <= value <= hi:
        raise UserError(f"{where}: {key} {value} out of range; use {lo:g} to {hi:g}")
    return float(value)


def _vector(where, key, value, lo=-MAX_VALUE, hi=MAX_VALUE) -> tuple:
    if not isinstance(value, list) or len(value) != 3:
        raise UserError(f"{where}: {key} must be a list of 3 numbers, not {json.dumps(value)}")
    return tuple(_number(where, f"{key}[{i}]", v, lo, hi) for i, v in enumerate(value))


def parse_light(item, where: str) -> Light:
    """One light of a --lights file, checked: one clear UserError for anything wrong."""
    if not isinstance(item, dict):
        raise UserError(f"{where}: a light must be an object, not {json.dumps(item)[:60]}")
    kind = item.get("type")
    if kind not in TYPES:
        raise UserError(
            f"{where}: unknown light type {json.dumps(kind)}; choose one of: {', '.join(TYPES)}"
        )
    allowed = set(COMMON) | set(PER_TYPE[kind])
    unknown = sorted(set(item) - allowed)
    if unknown:
        raise UserError(
            f"{where}: {kind} light has no key {unknown[0]!r}; it takes: "
            f"{', '.join(sorted(allowed))}"
        )
    if "energy" not in item:
        raise UserError(f"{where}: energy is missing (W, or W/m^2 for a SUN)")
    name = item.get("name", "")
    if not isinstance(name, str):
        raise UserError(f"{where}: name must be a string")
    use_shadow = item.get("use_shadow", True)
    if not isinstance(use_shadow, bool):
        raise UserError(f"{where}: use_shadow must be true or false")
    extra = {}
    for key in PER_TYPE[kind]:
        if key not in item:
            continue
        if key == "shape":
            if item[key] not in SHAPES:
                raise UserError(
                    f"{where}: unknown shape {json.dumps(item[key])}; choose one "
                    f"of: {', '.join(SHAPES)}"
                )
            extra[key] = item[key]
        elif key == "spot_size":
            extra[key] = _number(where, key, item[key], math.radians(1.0), math.pi)
        elif key == "spot_blend":
            extra[key] = _number(where, key, item[key], 0.0, 1.0)
        elif key == "angle":
            extra[key] = _number(where, key, item[key], 0.0, math.pi)
        else:
            extra[key] = _number(where, key, item[key], 0.0)
    scale = _vector(where, "scale", item.get("scale", [1, 1, 1]))
    if min(scale) <= 0.0:
        raise UserError(
            f"{where}: scale must be positive, not {list(scale)} (a mirrored light is not followed)"
        )
    light = Light(
        type=kind,
        name=name,
        energy=_number(where, "energy", item["energy"], 0.0),
        location=_vector(where, "location", item.get("location", [0, 0, 0])),
        rotation_euler=_vector(
            where, "rotation_euler", item.get("rotation_euler", [0, 0, 0]), -1e3, 1e3
        ),
        scale=scale,
        color=_vector(where, "color", item.get("color", [1, 1, 1]), 0.0),
        exposure=_number(where, "exposure", item.get("exposure", 0.0), -32.0, 32.0),
        use_shadow=use_shadow,
        extra=extra,
    )
    if kind == "AREA" and min(area_size(light)) <= 0.0:
        raise UserError(f"{where}: an AREA light needs a size above 0 (size, size_y, scale)")
    if max(light.power()) > MAX_POWER:
        raise UserError(
            f"{where}: colour x energy x 2^exposure is {max(light.power()):g}; "
            f"the model takes at most {MAX_POWER:g}"
        )
    if kind == "AREA" and max(area_size(light)) > MAX_VALUE:
        raise UserError(
            f"{where}: the AREA light is {max(area_size(light)):g} m wide "
            f"(size x scale); the model takes at most {MAX_VALUE:g}"
        )
    return light


def read_lights(path) -> list[Light]:
    """The lights of a --lights JSON file: a list of light objects (at most LIGHT_SLOTS)."""
    path = Path(path)
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise UserError(f"lights file {path} not found") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise UserError(f"lights file {path} cannot be read: {exc}") from None
    except json.JSONDecodeError as exc:
        raise UserError(f"lights file {path} is not JSON: {exc.msg} at line {exc.lineno}") from None
    except (ValueError, RecursionError) as exc:  # 4300-digit integers, deep nesting
        raise UserError(
            f"lights file {path} cannot be read as lights: "
            f"{str(exc).splitlines()[0][:80] or type(exc).__name__}"
        ) from None
    if not isinstance(data, list) or not data:
        raise UserError(f"lights file {path}: expected a non-empty list of lights")
    if len(data) > LIGHT_SLOTS:
        raise UserError(
            f"lights file {path}: {len(data)} lights; the model shades at most {LIGHT_SLOTS}"
        )
    return [
        parse_light(item, f"lights file {path.name}, light {i + 1}") for i, item in enumerate(data)
    ]


def ranked(lights: list, key=lambda light: light) -> list:
    """The order in which lights take the slots (docs/model.md "Lights"): Suns first, then
    by power (colour luminance x energy x 2^exposure), brightest first; ties by name."""
    from .model import REC709_LUMINANCE

    def rank(item):
        light = key(item)
        lum = sum(w * c for w, c in zip(REC709_LUMINANCE, light.power()))
        return (light.type != "SUN", -lum, light.name)

    return sorted(lights, key=rank)
