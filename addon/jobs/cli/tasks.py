"""The batch jobs as task graphs (jobs/graph.py): ``ctlab plan`` writes a job's tasks,
``ctlab task`` runs one of them, ``ctlab merge`` compares, plots and reports when the render
tasks are done; on this machine, on others, or on a render farm."""

from __future__ import annotations

import os
from pathlib import Path

from .matrix import job_inputs, say_done
from .options import (
    FLAMENCO,
    JOB,
    JOB_DIR,
    MATRIX_OPTIONS,
    OPENJD,
    OUT,
    PARITY,
    PARITY_HDRIS,
    TASK_ID,
    VERBOSE,
    Command,
    check_path,
    fill_defaults,
)
from .output import events, say


def run_plan(args) -> None:
    """``ctlab plan matrix [options] --out JOB``: the job's task graph (jobs/graph.py)."""
    from .. import graph

    if args.job == "parity":
        args.parity = True
    fill_defaults(args, "parity" if args.parity else "matrix")
    job, base, extra = job_inputs(args)
    out = check_path(args.out, "--out")
    plan = graph.plan_job(job, base, args.samples, **extra)
    graph.write_job_folder(out, plan, openjd=args.openjd, flamenco=args.flamenco)
    renders = [t for t in plan["tasks"] if t["kind"] == "render"]
    say(
        f"planned the {job} job: {len(renders)} render tasks and a merge -> "
        f"{out / 'plan.json'}"
        + (f", {out / 'openjd' / 'template.json'}" if args.openjd else "")
        + (f", {out / 'flamenco' / f'ctlab-{job}.js'}" if args.flamenco else "")
    )
    for t in plan["tasks"]:
        say(
            f"  {t['id']}  {t['kind']}"
            + (
                f"  {t['folder']}"
                if t["kind"] == "render"
                else f"  after {len(t['depends'])} tasks"
            )
        )


def _job_folder(args) -> Path:
    return Path(os.path.normpath(check_path(args.job_dir, "job folder")))


def run_task(args) -> None:
    """``ctlab task JOB ID``: one task of a plan (a finished one does nothing)."""
    from .. import graph

    result = graph.run_task(_job_folder(args), args.task_id, events(), args.verbose)
    if result["ran"] and "scene" in result:
        say(f"done: task {args.task_id} in {result['seconds']:.1f} s")


def run_merge(args) -> None:
    """``ctlab merge JOB``: the comparisons, plots and report from the job folder."""
    from .. import graph

    say_done(graph.merge(_job_folder(args), events(), args.verbose))


COMMANDS = (
    Command(
        "plan",
        "write a batch job's task graph (JOB/plan.json) for 'ctlab task' and 'ctlab merge', "
        "or a render farm",
        (
            JOB,
            OUT.but(help="the job folder"),
            OPENJD,
            FLAMENCO,
            PARITY.but(help="the Principled-parity job"),
            PARITY_HDRIS.but(
                help="Blender's bundled HDRIs for the parity job (default: %(default)s)"
            ),
            *MATRIX_OPTIONS,
        ),
        run_plan,
    ),
    Command(
        "task",
        "run one task of a planned job (done already: nothing)",
        (JOB_DIR, TASK_ID, VERBOSE),
        run_task,
    ),
    Command(
        "merge",
        "compare, plot and write the report of a planned job whose render tasks are done",
        (JOB_DIR, VERBOSE),
        run_merge,
    ),
)
