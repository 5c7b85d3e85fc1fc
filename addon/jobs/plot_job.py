"""The BRDF plots as a job: ``ctlab plot`` (``run_plot``) and the main job's four plots
(``report_plots``), the model evaluated by the chosen implementation at every configuration
of the plot (``evaluate_plot``: rendered once by ``render_plot``, then read from the cache,
jobs/plot_cache.py), reporting through pipeline.Events."""

from __future__ import annotations

from pathlib import Path

import bpy

from ..core import brdf_plot
from ..core.files import check_writable, refuse_overwrite
from ..core.model import G_MODELS
from ..core.settings import MatrixSettings
from .pipeline import Events


def evaluate_plot(
    settings: brdf_plot.PlotSettings, events: Events | None = None, verbose: bool = False
) -> dict:
    """The model of ``settings`` and of each variant (brdf_plot.PlotSettings.variants)
    evaluated by the chosen implementation at every configuration of the plot:
    {tag: brdf_plot.assemble(...)}, the variants' labels under "labels". Rendered once
    (render_plot), then read from the cache (jobs/plot_cache.py) while the settings, the
    code and Blender's version are the same."""
    from . import plot_cache

    return plot_cache.cached(settings, lambda: render_plot(settings, events, verbose))


def render_plot(
    settings: brdf_plot.PlotSettings, events: Events | None = None, verbose: bool = False
) -> dict:
    """evaluate_plot's results rendered, in a fresh empty scene."""
    from ..blender.model_eval import Evaluator

    events = events or Events()
    lay = brdf_plot.layout(settings)
    variants = settings.variants()
    base_views = tuple(
        dict.fromkeys(brdf_plot.BRDF_VIEWS + (brdf_plot.WEIGHT_VIEW,) + settings.views)
    )
    renders = [
        (tag, view, changes)
        for tag, _, changes in variants
        for view in (brdf_plot.BRDF_VIEWS if tag else base_views)
    ]
    bpy.ops.wm.read_factory_settings(use_empty=True)
    evaluator = Evaluator(
        settings.shader,
        lay.n,
        lay.l,
        settings.albedo,
        settings.metallic,
        settings.smoothness,
        settings.options(),
        verbose,
    )
    images: dict = {}
    for k, (tag, view, changes) in enumerate(renders):
        events.check()
        events.progress(k + 1, len(renders) + 1, f"{view}" + (f" ({tag})" if tag else ""))
        images.setdefault(tag, {})[view] = evaluator.render(settings.options(view, **changes))
    results = {
        tag: brdf_plot.assemble(
            lay, images[tag], settings.views if not tag else (), images[""][brdf_plot.WEIGHT_VIEW]
        )
        for tag, _, _ in variants
    }
    results["labels"] = {tag: label for tag, label, _ in variants}
    return results


def report_plots(base: MatrixSettings) -> list:
    """The main job's BRDF plots: (folder, label, PlotSettings) for a smooth and a rough
    sphere of the matrix (the smoothest below 1 and the roughest above 0, or the extremes
    where those coincide), each a metal and a dielectric (the last and first columns), with
    the base's albedo and switches and the other G models as variants."""
    cells = list(base.cells())
    smooth = sorted({c[3] for c in cells})
    metal = sorted({c[2] for c in cells})
    inner = [x for x in smooth if 0.0 < x < 1.0] or smooth
    rows = (inner[-1], inner[0]) if inner[-1] != inner[0] else (smooth[-1], smooth[0])
    compare = tuple(("g", g) for g in G_MODELS if g != base.model.g_model)
    out = []
    for kind, s in zip(("smooth", "rough"), dict.fromkeys(rows)):
        for m in dict.fromkeys((metal[-1], metal[0])):
            what = "metal" if m >= 0.5 else "dielectric"
            out.append(
                (
                    f"m{m:.2f}_s{s:.2f}",
                    f"{kind} {what}: metallic {m:.2f}, smoothness {s:.2f}",
                    brdf_plot.PlotSettings(
                        metallic=m,
                        smoothness=s,
                        albedo=base.albedo,
                        g_model=base.model.g_model,
                        diffuse_model=base.model.diffuse_model,
                        units=base.model.units,
                        energy=base.model.energy,
                        shader="osl",
                        compare=compare,
                    ),
                )
            )
    return out


def run_plot(
    settings: brdf_plot.PlotSettings, out: Path, events: Events | None = None, verbose: bool = False
) -> dict:
    """``ctlab plot``: the BRDF's slice, lobes and directional albedo from the model's own
    code, written into ``out`` whole (plot_figures.write_plot). Returns plot.json's data."""
    from ..core import plot_figures

    events = events or Events()
    refuse_overwrite([], [Path(out) / "plot.json"], [out])  # not in the cache
    plot_figures.refuse_blocked(out, plot_figures.planned_names(settings))  # before renders
    check_writable(out)
    results = evaluate_plot(settings, events, verbose)
    events.check()
    events.note("writing the plots")
    return plot_figures.write_plot(
        Path(out),
        settings,
        results,
        {"blender": bpy.app.version_string, "implementation": settings.shader},
        events.warn,
    )
