"""Cook-Torrance Lab command line.

python scripts/ctlab.py render --shader osl --out DIR [...]   (bpy as a Python module)
blender -b -P scripts/ctlab.py -- render --shader osl --out DIR [...]
"""

import os
import signal
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
if ROOT not in sys.path:
    sys.path.insert(0, ROOT)

# Ctrl-C and SIGTERM are handled by a watcher thread (addon/jobs/signals.py): block them
# before Blender starts its threads, so that no thread of Blender's swallows them.
signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT, signal.SIGTERM})

import bpy  # noqa: E402  (Blender as a module, or the running Blender)

from addon.jobs import signals  # noqa: E402
from addon.jobs.cli import main  # noqa: E402  (the Blender layer exposes its bundled modules)

if __name__ == "__main__":
    signals.install()
    argv = sys.argv[sys.argv.index("--") + 1 :] if "--" in sys.argv else sys.argv[1:]
    try:
        code = main(argv)
    except BaseException:
        signals.yield_to_cancel()  # an error caused by a cancel's removals is not reported
        raise
    signals.yield_to_cancel()
    if bpy.app.background and not bpy.app.binary_path.endswith("python"):
        sys.stdout.flush()
    sys.exit(code)
