"""``ctlab matrix``: the main job, Cook-Torrance against Principled with a report, or with
--parity the Principled-parity check; run here or by --workers local processes, as the task
graph of jobs/graph.py. Its inputs (``job_inputs``) and last line (``say_done``) serve
``plan`` and ``merge`` too (cli/tasks.py)."""

from __future__ import annotations

from pathlib import Path

from .options import MATRIX_OPTIONS, OUT, PARITY, PARITY_HDRIS, WORKERS, Command, check_path
from .output import events, say
from .sphere_matrix import settings_from
from .. import pipeline
from ...core.paths import safe_name


def job_inputs(args) -> tuple:
    """("matrix" or "parity", base settings, the parity job's HDRIs and name) from the
    matrix options, validated."""
    base = settings_from(args, "osl", "full")
    if not args.parity:
        return "matrix", base, {}
    if base.lights:  # one run under the lights, with --hdri or the first parity HDRI
        hdris = [Path(base.hdri)] if args.hdri else pipeline.parity_hdris(args.parity_hdris)[:1]
        name = safe_name(Path(base.lights_file).stem, "lights")  # never "..": stays in --out
    else:
        hdris = [Path(base.hdri)] if args.hdri else pipeline.parity_hdris(args.parity_hdris)
        name = None
    return "parity", base, {"hdris": hdris, "name": name}


def say_done(result: dict) -> None:
    """The last line of a matrix or parity job (run here, or merged from its tasks)."""
    if result.get("job") == "parity":
        say(
            f"done: parity {'holds' if result['holds'] else 'FAILS'} (every sphere's mean "
            f"CIEDE2000 <= {pipeline.PARITY_BOUND}); open {result['report']}"
        )
        return
    de = {k: r["overall"]["ciede2000_mean"] for k, r in result["comparisons"].items()}
    psnr = result["comparisons"]["compare"]["overall"]["psnr_db"]
    say(
        f"done: mean CIEDE2000 against Principled {de['compare']:.2f} "
        f"(PSNR {'-' if psnr is None else f'{psnr:.2f}'} dB); split-sum "
        f"against the reference {de['compare_split_sum']:.2f} (corrected "
        f"{de['compare_split_sum_corrected']:.2f}), Unity {de['compare_unity']:.2f}; "
        f"node group against OSL {de['compare_nodes']:.3f}; open {result['report']}"
    )


def run(args) -> None:
    """The main job (or, with --parity, the Principled-parity check)."""
    if args.parity:
        return run_parity(args)
    workers = WORKERS.check(args.workers)
    _, base, _ = job_inputs(args)
    out = check_path("out/matrix" if args.out is None else args.out, "--out")
    from .. import graph

    result = graph.run_matrix(base, args.samples, out, events(), args.verbose, workers)
    say_done(dict(result, job="matrix"))


def run_parity(args) -> None:
    """The Principled-parity check (graph.run_parity) for each HDRI of --parity-hdris, or
    for --hdri."""
    workers = WORKERS.check(args.workers)
    _, base, extra = job_inputs(args)
    out = check_path("out/parity" if args.out is None else args.out, "--out")
    from .. import graph

    result = graph.run_parity(
        base,
        extra["hdris"],
        args.samples,
        out,
        events(),
        args.verbose,
        name=extra["name"],
        workers=workers,
    )
    say_done(dict(result, job="parity"))


COMMAND = Command(
    "matrix",
    "the main job: Cook-Torrance vs Principled, with a report",
    (
        OUT.but(
            required=False, help="output folder (default out/matrix; out/parity with --parity)"
        ),
        PARITY,
        PARITY_HDRIS,
        WORKERS,
        *MATRIX_OPTIONS,
    ),
    run,
)
