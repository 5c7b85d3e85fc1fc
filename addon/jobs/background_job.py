"""The batch comparison (``ctlab matrix``) run in a separate process, so Blender's interface
stays responsive: the child reports its pipeline's events as JSON lines ($CTLAB_JSON_EVENTS),
read on a thread; ``poll`` reports the fraction done, ``cancel`` stops it between two renders.

The child is Blender itself in background mode (``blender -b --factory-startup``) or, for
Blender as a Python module, the same Python interpreter. It imports this package under a
private name from its folder, so an installed extension and a checkout both work. Every
render folder is written whole (renderer.render renames finished files into place). Cancel is
cooperative: the parent creates the file named by $CTLAB_CANCEL_FILE, which the command line
checks between steps (pipeline.Events.cancelled), so a cancelled job keeps every finished output and
leaves no partial file. (A SIGTERM handler in the child was not run while Blender rendered:
the job went on to the end.) A child that has not stopped KILL_AFTER seconds later is killed.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import bpy

from ..core.cache import cache_dir
from ..core.files import PACKAGE_ROOT

# The child's program: import the package from its folder and run the command line.
_CHILD = """
import importlib.util, signal, sys
signal.pthread_sigmask(signal.SIG_BLOCK, {{signal.SIGINT, signal.SIGTERM}})
spec = importlib.util.spec_from_file_location(
    "ctlab_job", {init!r}, submodule_search_locations=[{root!r}])
pkg = importlib.util.module_from_spec(spec)
sys.modules["ctlab_job"] = pkg
import bpy
getattr(bpy.utils, "expose_bundled_modules", lambda: None)()
from ctlab_job.addon.jobs import signals
from ctlab_job.addon.jobs.cli.main import run_and_exit
signals.install()
run_and_exit({argv!r})
"""


def child_command(argv: list) -> list:
    """The command line of a child process running ``ctlab`` with ``argv``."""
    code = _CHILD.format(
        init=str(PACKAGE_ROOT / "__init__.py"), root=str(PACKAGE_ROOT), argv=list(argv)
    )
    if bpy.app.binary_path and not getattr(bpy.app, "module", False):
        return [
            bpy.app.binary_path,
            "-b",
            "--factory-startup",
            "--python-exit-code",
            "1",
            "--python-expr",
            code,
        ]
    return [sys.executable, "-c", code]


class Job:
    """One running batch command. States: running, cancelling, done, failed, cancelled."""

    def __init__(self, argv: list, out_dir: Path):
        self.out_dir = Path(out_dir)
        self.fraction = 0.0
        self.message = "starting"
        self.state = "running"
        self.lines: list = []
        self.cancel_file = Path(tempfile.gettempdir()) / f"ctlab-cancel-{os.getpid()}-{id(self)}"
        self.cancel_file.unlink(missing_ok=True)
        # the child uses the add-on's cache folder (it has no preferences to read it from)
        env = dict(
            os.environ,
            PYTHONUNBUFFERED="1",
            CTLAB_CANCEL_FILE=str(self.cancel_file),
            CTLAB_JSON_EVENTS="1",
            CTLAB_CACHE=str(cache_dir()),
        )
        self.process = subprocess.Popen(
            child_command(argv),
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
            env=env,
        )
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self) -> None:
        for line in self.process.stdout:
            line = line.rstrip()
            self.lines.append(line)
            event = None
            if line.startswith("{"):
                try:
                    event = json.loads(line)
                except ValueError:
                    pass
            if isinstance(event, dict) and event.get("event") == "progress":
                k, n = int(event["step"]), int(event["total"])
                self.fraction = (k - 1) / n
                self.message = f"{k}/{n}: {str(event['message']).split(':')[0]}"
            elif line.startswith("ctlab: error:"):
                self.message = line[len("ctlab: error:") :].strip()

    KILL_AFTER = 30.0  # seconds a cancelled child may take to finish its render

    def poll(self) -> str:
        """Update and return the state (never blocks)."""
        if self.state not in ("running", "cancelling"):
            return self.state
        if self.process.poll() is None:
            if self.state == "cancelling" and time.monotonic() > self._kill_at:
                self.process.kill()
            return self.state
        self._reader.join(timeout=5)
        self.cancel_file.unlink(missing_ok=True)
        code = self.process.returncode
        if self.state == "cancelling":
            self.state, self.message = "cancelled", "cancelled; finished renders kept"
        elif code == 0:
            self.state, self.fraction, self.message = "done", 1.0, "done"
        else:
            self.state = "failed"
            if not self.message or self.message[0].isdigit() or self.message == "starting":
                self.message = f"failed (exit status {code}); see the console"
        return self.state

    def cancel(self) -> None:
        """Ask the child to stop after the step in progress; killed if it takes too long."""
        if self.state == "running":
            self.state, self.message = "cancelling", "cancelling after the current render"
            self._kill_at = time.monotonic() + self.KILL_AFTER
            self.cancel_file.touch()

    @property
    def report(self) -> Path:
        return self.out_dir / "report.html"
