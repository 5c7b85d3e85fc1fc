"""The command line: ``render``, ``compare``, ``bake``, ``matrix``, ``plot``, ``scene``,
``export``, and the batch jobs as task graphs: ``plan``, ``task``, ``merge``; scripts/ctlab.py
is the entry. It maps arguments onto settings (core.settings) and runs the pipeline
(jobs/pipeline.py; ``scene``: jobs/scene_job.py; ``export``: jobs/export_job.py).

One module per command (cli/render.py, cli/compare.py, cli/bake.py, cli/matrix.py,
cli/tasks.py for plan, task and merge, cli/plot.py, cli/scene.py, cli/export.py); every
option declared once (cli/options.py), the sphere matrix's settings made from them
(cli/sphere_matrix.py), what is printed (cli/output.py), the parser and the command lines
callers write (cli/parser.py ``argv``), and the entry (cli/main.py).

Bad input gets a one-line message naming the problem and exit status 2, and nothing is
written. Blender's own per-tile output goes to a log file in the system temp folder; the
command prints its own progress, or, with $CTLAB_JSON_EVENTS set (the background job), one
JSON object per event. A job stops between steps when the file named by $CTLAB_CANCEL_FILE
exists (exit status 130; finished outputs are kept).
"""

from .main import EXIT_BAD_INPUT, EXIT_CANCELLED, main

__all__ = ["EXIT_BAD_INPUT", "EXIT_CANCELLED", "main"]
