"""The background jobs (a comparison, a BRDF plot) the operators start: their table, the
timer that follows them, and their end when the add-on is removed."""

from __future__ import annotations

from pathlib import Path

import bpy

# ----------------------------------------------------------------------------------------
# The comparison job in the background

JOBS: dict = {}  # "comparison", "plot" -> background_job.Job
PLOT_IMAGE = "Cook-Torrance BRDF Plot"


def _job_tick():
    """Timer: copy each job's progress into the window manager and redraw; when a job ends,
    act on it once (open the comparison's report, load the BRDF plot into an image). Stops
    when no job runs."""
    wm = bpy.context.window_manager
    running = False
    for kind, job in list(JOBS.items()):
        state = job.poll()
        if kind == "comparison":
            wm.ctlab_job_progress, wm.ctlab_job_message, wm.ctlab_job_state = (
                job.fraction,
                job.message,
                state,
            )
        else:
            wm.ctlab_plot_message, wm.ctlab_plot_state = job.message, state
        if state in ("running", "cancelling"):
            running = True
        elif not getattr(job, "handled", False):
            job.handled = True
            if getattr(job, "staging", None) is not None:  # the scene job's file copy
                import shutil

                shutil.rmtree(job.staging, ignore_errors=True)
            if (
                kind == "comparison"
                and state == "done"
                and job.open_report
                and not bpy.app.background
            ):
                bpy.ops.wm.url_open(url=job.report.as_uri())
            elif kind == "plot" and state == "done":
                try:
                    show_plot(job.out_dir / "plot.png")
                except (RuntimeError, OSError) as exc:  # the file went away meanwhile
                    job.state = "failed"
                    wm.ctlab_plot_message, wm.ctlab_plot_state = (
                        f"cannot open plot.png: {exc}",
                        "failed",
                    )
    for window in wm.windows:
        for area in window.screen.areas:
            if area.type in ('VIEW_3D', 'PROPERTIES', 'IMAGE_EDITOR'):
                area.tag_redraw()
    return 0.5 if running else None


def _start_tick() -> None:
    if not bpy.app.timers.is_registered(_job_tick):  # one timer, however many jobs
        bpy.app.timers.register(_job_tick, first_interval=0.5)


def show_plot(path: Path) -> bpy.types.Image:
    """The plot's PNG as the add-on's image PLOT_IMAGE (reloaded when it exists), shown in
    every open Image Editor. A user's image of that name is never changed (blender/owned.py:
    ours is then "Cook-Torrance BRDF Plot.001")."""
    from ...blender import owned

    if not Path(path).is_file():
        raise OSError(f"{path} does not exist")
    image = owned.find(bpy.data.images, PLOT_IMAGE, owned.PLOT_IMAGE)
    if image is None:
        image = owned.mark(bpy.data.images.load(str(path)), owned.PLOT_IMAGE)
        image.name = PLOT_IMAGE
    else:
        if image.packed_file is not None:  # packed by the user: show the new file
            image.unpack(method='REMOVE')
        image.filepath = str(path)
        image.reload()
    for window in bpy.context.window_manager.windows:
        for area in window.screen.areas:
            if area.type == 'IMAGE_EDITOR':
                area.spaces.active.image = image
    return image


def _comparison_running(op) -> bool:
    """Whether a comparison job runs (reported as the operator's error)."""
    running = JOBS.get("comparison")
    if running is not None and running.poll() in ("running", "cancelling"):
        op.report({'ERROR'}, "a comparison is already running; cancel it first")
        return True
    return False


def _start_comparison(context, job) -> None:
    """Follow a started comparison job in the sidebar (the timer polls it)."""
    JOBS["comparison"] = job
    wm = context.window_manager
    wm.ctlab_job_state, wm.ctlab_job_message, wm.ctlab_job_progress = "running", "starting", 0.0
    _start_tick()


def stop_jobs() -> None:
    """On unregister: no child process or timer may outlive the add-on."""
    for kind in list(JOBS):
        job = JOBS.pop(kind)
        if job.process.poll() is None:
            job.process.kill()
            job.process.wait()
    # a timer left registered at exit hangs Blender's shutdown (measured: a second job
    # registered a second timer and the process never exited)
    while bpy.app.timers.is_registered(_job_tick):
        bpy.app.timers.unregister(_job_tick)
