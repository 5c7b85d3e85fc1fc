"""The sphere matrix's settings (core.settings.MatrixSettings) from its options
(cli/options.py ``MATRIX_OPTIONS``: ``render``, ``matrix``, ``plan``), validated: bad input
is one line (UserError) before anything is written."""

from __future__ import annotations

import math

from .options import SAMPLES, parse_grid, parse_vector
from ...core.errors import UserError
from ...core.model import VIEWS, ModelOptions, indirect_light
from ...core.paths import input_file
from ...core.settings import MatrixSettings

FLOAT32_MAX = 3.4028234663852886e38


def settings_from(args, shader: str, view: str) -> MatrixSettings:
    """The scene and model settings from the command line, validated."""
    if view not in VIEWS and view != "all":
        raise UserError(f"unknown view {view!r}; choose one of: {', '.join(VIEWS)}")
    rows, cols = parse_grid(args.grid)
    SAMPLES.check(args.samples, "samples")
    ibl = args.ibl or indirect_light(shader)
    # degrees on the command line, radians inside (the Mapping node's unit)
    if not (math.isfinite(args.hdri_rotation) and abs(args.hdri_rotation) <= FLOAT32_MAX):
        raise UserError(
            f"hdri rotation {args.hdri_rotation} out of range; use a finite number of degrees"
        )
    model = ModelOptions(
        view=view,
        g_model=args.g_model,
        diffuse_model=args.diffuse_model,
        units=args.units,
        energy=args.energy,
        ibl=ibl,
        env_samples=args.env_samples,
        env_visibility=args.env_visibility,
        seed=args.seed,
        light_transport=args.light_transport,
    )
    hdri = (
        str(
            input_file(
                args.hdri,
                "HDRI",
                missing=f"HDRI not found: {args.hdri} (give an "
                "existing equirectangular .exr or .hdr file)",
            )
        )
        if args.hdri
        else ""
    )
    return MatrixSettings(
        rows=rows,
        cols=cols,
        hdri=hdri,
        hdri_strength=args.hdri_strength,
        hdri_rotation=math.radians(args.hdri_rotation),
        sun_to_light=parse_vector(args.sun_dir, 3, "sun direction"),
        sun_strength=args.sun_strength,
        albedo=parse_vector(args.albedo, 3, "albedo"),
        shader=shader,
        principled_distribution=args.principled_distribution,
        width=args.size,
        height=args.size,
        model=model,
        **lights_from(args),
        **textures_from(args),
    )


def textures_from(args) -> dict:
    """The spheres' albedo texture and normal map (core/textures.py), each checked (one line
    for a bad image; a warning for a normal map that does not look like one)."""
    from ...core.textures import matrix_textures
    from .output import warn

    found, warnings = matrix_textures(
        args.albedo_texture, args.normal_map, args.textured, args.normal_strength
    )
    for message in warnings:
        warn(message)
    return found


def lights_from(args) -> dict:
    """The --lights file's lights, read and checked (one clear line for a bad file)."""
    if not args.lights:
        return {}
    from ...core.lights import read_lights

    path = input_file(args.lights, "--lights", missing=f"lights file {args.lights} not found")
    return {"lights": tuple(read_lights(path)), "lights_file": str(path)}
