"""The merge of a batch job's task graph (jobs/graph.py, ``merge``): the comparisons, the
BRDF plots and the report, computed from the job folder alone, after ``merge`` has checked
every render task and taken the merge lock (jobgraph.merge_lock)."""

from __future__ import annotations

from pathlib import Path

from . import pipeline, plot_job
from ..core import energy, jobgraph
from ..core.compare import compare, read_image
from ..core.errors import UserError
from ..core.report import write_parity_report, write_report


def matrix_labels() -> dict:
    """{folder: label} of the main job's renders, as the report and the progress name them."""
    labels = {folder: label for folder, label, *_ in pipeline.MATRIX_RENDERS}
    labels.update(
        {
            folder: f"White furnace, {pipeline.furnace_label(g, e)}"
            for folder, g, e in pipeline.FURNACE_RENDERS
        }
    )
    return labels


def read_scene(job_dir: Path, folder: str) -> dict:
    """A render folder's scene.json, read as input (jobgraph.read_json: a regular file, not
    blocking, bounded)."""
    path = Path(job_dir) / folder / "scene.json"
    scene = jobgraph.read_json(path, "render description", jobgraph.MAX_PLAN_BYTES)
    if not isinstance(scene, dict) or not isinstance(scene.get("render_seconds"), (int, float)):
        raise UserError(f"{path} is not a render's description; re-run its task")
    return scene


def merge_matrix(out, plan, base, events, verbose, steps) -> dict:
    """The main job's comparisons, furnace albedos, BRDF plots and report.html."""
    steps = steps or 2
    labels = matrix_labels()
    folders = [t["folder"] for t in jobgraph.render_tasks(plan)]
    scenes = {f: read_scene(out, f) for f in folders}
    timings = {labels[f]: scenes[f]["render_seconds"] for f in folders}
    events.check()
    events.progress(steps - 1, steps, "comparing; the BRDF plots")
    results = {
        cmp_dir: compare(out / a, out / b, out / cmp_dir)
        for cmp_dir, a, b in pipeline.MATRIX_COMPARISONS
    }
    furnace = {
        pipeline.furnace_label(g, e): energy.directional_albedo(
            read_image(out / folder / "render.exr"), scenes[folder]
        )
        for folder, g, e in pipeline.FURNACE_RENDERS
    }
    plots = []
    for name, label, plot in plot_job.report_plots(base):
        events.check()
        events.note(f"BRDF plot: {label}")
        inner = pipeline.Events(note=pipeline._nothing, cancelled=events.cancelled)
        plots.append(
            (label, f"plots/{name}", plot_job.run_plot(plot, out / "plots" / name, inner, verbose))
        )
    events.progress(steps, steps, "writing the report")
    report = write_report(
        out,
        [
            (a, b, cmp_dir, labels[a], labels[b], results[cmp_dir])
            for cmp_dir, a, b in pipeline.MATRIX_COMPARISONS[:5]
        ],
        scenes["cook_torrance"],
        timings,
        attribution=[(s[1], results[s[0]], *s[2:]) for s in pipeline.ATTRIBUTION],
        furnace=furnace,
        plots=plots,
    )
    return {"job": "matrix", "report": report, "comparisons": results}


def merge_parity(out, plan, events, steps) -> dict:
    """Each parity run's comparison against its bound, and the parity report."""
    steps = steps or 1
    names = list(dict.fromkeys(t["folder"].split("/")[0] for t in jobgraph.render_tasks(plan)))
    entries = []
    for name in names:
        events.check()
        result = compare(
            out / name / "cook_torrance", out / name / "principled", out / name / "compare"
        )
        worst = max(c["ciede2000_mean"] for c in result["cells"])
        events.note(
            f"{name}: mean CIEDE2000 {result['overall']['ciede2000_mean']:.2f}, "
            f"worst sphere {worst:.2f} (bound {pipeline.PARITY_BOUND})"
        )
        entries.append((name, result, read_scene(out, f"{name}/cook_torrance")))
    events.progress(steps, steps, "writing the report")
    report = write_parity_report(out, entries, pipeline.PARITY_BOUND)
    holds = all(
        max(c["ciede2000_mean"] for c in r["cells"]) <= pipeline.PARITY_BOUND for _, r, _ in entries
    )
    return {
        "job": "parity",
        "holds": holds,
        "report": report,
        "comparisons": {n: r for n, r, _ in entries},
    }
