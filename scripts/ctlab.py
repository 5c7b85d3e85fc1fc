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

import bpy  # noqa: E402, F401  (Blender as a module, or the running Blender: started now)

from addon.jobs import signals  # noqa: E402
from addon.jobs.cli.main import run_and_exit  # noqa: E402  (the Blender layer exposes its bundled modules)

if __name__ == "__main__":
    signals.install()
    argv = sys.argv[sys.argv.index("--") + 1 :] if "--" in sys.argv else sys.argv[1:]
    run_and_exit(argv)
