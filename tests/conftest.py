"""Shared by every tier: the repository and tests/ on sys.path (helpers.py, reference_model.py,
chi2.py), and a private cache. No Blender here: the tiers are folders,

- unit/    the pure core, the node group's description, the docs and the architecture, without
           bpy (./scripts/test.sh --quick runs this tier alone, in seconds);
- render/  real Blender (bpy 4.5 or 5.2 as a module): the builders, the interface and small
           real renders, checked against values derived independently of the shader;
- slow/    converged renders, the samplers' chi-square tests and the BRDF plots.

render/ and slow/ take Blender's fixtures from blender_fixtures.py."""

import os
import shutil
import signal
import sys
import tempfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))
# A private cache for the session, made by the first process (the workers inherit it) and
# removed by that process at the end; a CTLAB_CACHE set by the caller is theirs, kept.
_CACHE = None
if "CTLAB_CACHE" not in os.environ:
    _CACHE = tempfile.mkdtemp(prefix="ctlab-test-cache-")
    os.environ["CTLAB_CACHE"] = _CACHE
# Mesa's shader cache (EEVEE's shaders as llvmpipe compiled them) stays where the driver keeps
# it by default, $XDG_CACHE_HOME or ~/.cache: under the private XDG_CACHE_HOME below, EEVEE
# would compile its own shaders cold in every session (its first render: 47 s on 5.2, against
# 5 s with the driver's cache warm). The first run on a machine still pays it.
os.environ.setdefault(
    "MESA_SHADER_CACHE_DIR", os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
)
os.environ.setdefault("XDG_CACHE_HOME", os.environ["CTLAB_CACHE"])


# Blender as a module can hang when the process exits: in the fresh-clone CI on bpy 4.5.15 the
# suite printed its summary, then a C++ static's destructor in bpy waited for ever on a
# condition variable (gdb: GlobalState::~GlobalState in __run_exit_handlers, an EEVEE GPU
# worker thread still parked). So a run that loaded bpy leaves at once, with pytest's own exit
# status, once pytest is done (the summary and the cache are written by then).
_EXIT = {"status": 0}


def pytest_sessionfinish(session, exitstatus):
    _EXIT["status"] = int(exitstatus)


def pytest_unconfigure(config):
    if _CACHE is not None:
        shutil.rmtree(_CACHE, ignore_errors=True)
    if "bpy" in sys.modules:
        # Blender's own session folder (/tmp/blender_XXXXXX), which its exit would remove
        session_tmp = Path(sys.modules["bpy"].app.tempdir)
        if session_tmp.name.startswith("blender_"):
            shutil.rmtree(session_tmp, ignore_errors=True)
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(_EXIT["status"])


@pytest.fixture
def alarm():
    """A check that could block (a read of a named pipe) fails the test instead of hanging
    it: SIGALRM after 60 s raises in the blocked call."""

    def on_alarm(*_):
        raise AssertionError("blocked: the command hung on its input")

    old = signal.signal(signal.SIGALRM, on_alarm)
    signal.alarm(60)
    yield
    signal.alarm(0)
    signal.signal(signal.SIGALRM, old)


def pytest_configure(config):
    config.addinivalue_line(
        "markers",
        "one_series: its subject does not depend on Blender's version; CI runs it on the "
        "newest series only (./scripts/test.sh --series-subset leaves it out)",
    )


# The files that take longest (seconds of test time, 5.2, summed from --durations over two
# workers on 2 cores; docs/testing.md), heaviest first. Over workers (./scripts/test.sh, xdist's
# --dist loadfile --no-loadscope-reorder) files are handed out in collection order, so a
# worker never starts a long file last while the other has nothing left: the longest go
# first, the short ones fill in. Only the order changes, and only in workers.
LONGEST_FILES = (
    "slow/test_scene_transport_nodes.py",  # 140: 18 world renders, the residual quadratures
    "slow/test_scene_transport.py",  # 130: 13 converged renders, the mirror in a real scene
    "render/test_task_graph.py",  # 90: the main job, as processes, the killed task
    "render/test_node_group.py",  # 75: EEVEE against Cycles, every term view
    "render/test_ibl_bake.py",  # 65
    "render/test_ui_jobs.py",  # 63 with test_ui_materials.py and test_ui_panels.py
    "slow/test_scene_residual.py",  # 55
    "slow/test_brdf_plot.py",  # 52
    "render/test_scene_job.py",  # 45
    "render/test_travel.py",  # 45
    "render/test_fuzz_cli.py",  # 37
    "render/test_baked_modes.py",  # 32
    "slow/test_reference_ibl.py",  # 32
    "render/test_light_follow.py",  # 31
    "render/test_writes.py",  # 30
    "render/test_lights.py",  # 30
)


def pytest_collection_modifyitems(config, items):
    if not os.environ.get("PYTEST_XDIST_WORKER"):
        return
    rank = {name: k for k, name in enumerate(LONGEST_FILES)}

    def key(item):
        path = Path(str(item.path)).resolve().relative_to(ROOT / "tests").as_posix()
        return rank.get(path, len(rank))

    items.sort(key=key)  # stable: a file's tests keep their order
