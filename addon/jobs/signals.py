"""Ctrl-C (SIGINT) and SIGTERM cancel a job at once: one line on stderr, exit status 130,
every finished output kept whole, no partial file, no traceback.

Python runs a signal handler only in the main thread and only between its own instructions;
a Cycles render is one long call into Blender, and Blender swallows an exception raised in
the Python callbacks it makes (a KeyboardInterrupt, say: the render went on, and a Ctrl-C
was noticed when it ended). So both signals are blocked in every thread (``block``, before
Blender starts its threads) and a watcher thread waits for them. It does not unwind the main
thread: every file the project writes is staged under a temporary name and renamed when
whole (core.files), so the watcher removes the temporaries being written and Blender's
session folder, prints the line and ends the process.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import signal
import sys
import threading
import time
from pathlib import Path

from ..core.files import live_temporaries

SIGNALS = {signal.SIGINT, signal.SIGTERM}
MESSAGE = "ctlab: cancelled; finished outputs are kept\n"
_watcher = None
_cancelling = threading.Event()  # set by the watcher before it removes anything
_stderr = 2  # a copy of the process's stderr taken at install: a writer that sends
# fd 2 elsewhere for a moment (renderer.quiet) cannot swallow the line


def block() -> None:
    """Block SIGINT and SIGTERM in this thread and the threads it starts from now on (call
    it before importing bpy)."""
    signal.pthread_sigmask(signal.SIG_BLOCK, SIGNALS)


def _cancel() -> None:
    """Remove what a normal exit would have (the temporaries being written, Blender's own
    session folder blender_XXXX in the system's temporary folder) and end the process."""
    _cancelling.set()
    try:
        bpy = sys.modules.get("bpy")
        session = Path(bpy.app.tempdir) if bpy is not None and bpy.app.tempdir else None
        if session is not None and session.name.startswith("blender_"):
            _remove(session)  # Blender's threads may still write into it, as ours may
        for path in live_temporaries():
            _remove(Path(path))
        with contextlib.suppress(OSError):  # stderr on a full disk, or a pipe closed
            os.write(_stderr, MESSAGE.encode())
    finally:
        os._exit(130)  # whatever failed above: the main thread waits for this (yield_to_cancel)


def _remove(path: Path, tries: int = 40) -> None:
    """Remove a temporary that the main thread, which runs on meanwhile, may still be
    writing: again until it is gone. A file it adds to a folder between rmtree's listing and
    its rmdir (the OSL compile's output) leaves the folder standing; once the folder is gone,
    no new file can appear in it."""
    for _ in range(tries):
        if path.is_dir() and not path.is_symlink():
            shutil.rmtree(path, ignore_errors=True)
        else:
            with contextlib.suppress(OSError):
                path.unlink()
        if not os.path.lexists(path):
            return
        time.sleep(0.005)


def yield_to_cancel() -> None:
    """Called by the main thread before it reports an error or exits: when a cancel has
    begun, wait for the watcher to end the process with 130. Its removals can make the work
    under way fail (an OSL compile whose folder is gone), and that failure must not win the
    race with exit status 2 and a second line."""
    if _cancelling.is_set():
        threading.Event().wait()  # the watcher's os._exit ends the process


def _watch() -> None:
    signal.sigwait(SIGNALS)
    _cancel()


def install() -> None:
    """Cancel on SIGINT and SIGTERM from now on (once per process)."""
    global _watcher, _stderr
    if _watcher is not None:
        return
    try:
        _stderr = os.dup(2)
    except OSError:
        _stderr = 2
    block()
    _watcher = threading.Thread(target=_watch, name="ctlab-signals", daemon=True)
    _watcher.start()
