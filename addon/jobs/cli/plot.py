"""``ctlab plot``: the BRDF plotted from the model's own code (jobs/plot_job.py
``run_plot``, core/brdf_plot.py): the theta_h x theta_d slice, lobes and directional albedo."""

from __future__ import annotations

from .options import (
    ALBEDO,
    COMPARE,
    DIFFUSE,
    ENERGY,
    G,
    METALLIC,
    OUT,
    SHADER,
    SMOOTHNESS,
    UNITS,
    VERBOSE,
    VIEW,
    Command,
    check_path,
    parse_vector,
    vector_text,
)
from .output import events, say
from .. import plot_job
from ...core import model


def plot_settings_from(args):
    """The plot's settings from the command line, validated (core.brdf_plot.PlotSettings)."""
    from ...core.brdf_plot import PlotSettings, parse_compare

    views = [v.strip() for item in (args.view or ()) for v in item.split(",") if v.strip()]
    return PlotSettings(
        metallic=args.metallic,
        smoothness=args.smoothness,
        albedo=parse_vector(args.albedo, 3, "albedo"),
        g_model=args.g_model,
        diffuse_model=args.diffuse_model,
        units=args.units,
        energy=args.energy,
        shader=args.shader,
        views=tuple(views),
        compare=parse_compare(args.compare),
    )


def run(args) -> None:
    """The BRDF plotted from the model's own code (plot_job.run_plot)."""
    settings = plot_settings_from(args)
    out = check_path(args.out, "--out")
    say(
        f"plotting the {settings.shader} model: metallic {settings.metallic:g}, smoothness "
        f"{settings.smoothness:g} -> {out}"
    )
    data = plot_job.run_plot(settings, out, events(), args.verbose)
    say(
        f"done: f_r up to {data['slice']['max']:.4g} /sr on the slice, mean directional "
        f"albedo {data['albedo']['mean_total']:.3f}; slice.exr, slice.png, lobe.svg, "
        f"albedo.csv and plot.json in {out}"
    )


COMMAND = Command(
    "plot",
    "the BRDF plotted from the model's own code: the theta_h x theta_d slice, lobes and "
    "directional albedo",
    (
        OUT,
        METALLIC,
        SMOOTHNESS,
        # a plot shows one material, by default the model's grey rather than the matrix's gold
        ALBEDO.but(
            default=vector_text(model.DEFAULT_ALBEDO),
            help="R,G,B linear albedo, each 0 to 1 (default %(default)s)",
        ),
        G,
        DIFFUSE,
        # the values only: the plot has no light transport and no direct light
        UNITS.but(help="|".join(UNITS.values)),
        ENERGY.but(help="|".join(ENERGY.values)),
        SHADER,
        VIEW.but(
            default=None,
            repeat=True,
            help="also slice these term views (comma list, repeatable): D, F, G, "
            "specular_brdf, diffuse_brdf, NdotL, NdotV, NdotH, VdotH",
        ),
        COMPARE,
        VERBOSE,
    ),
    run,
)
