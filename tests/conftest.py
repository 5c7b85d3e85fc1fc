"""Shared by every tier: the repository and tests/ on sys.path (helpers.py, reference_model.py,
chi2.py), and a private cache. No Blender here: the tiers are folders,

- unit/    the pure core, the node group's description, the docs and the architecture, without
           bpy (./scripts/test.sh --quick runs this tier alone, in seconds);
- render/  real Blender (bpy 4.5 or 5.2 as a module): the builders, the interface and small
           real renders, checked against values derived independently of the shader;
- slow/    converged renders, the samplers' chi-square tests and the BRDF plots.

render/ and slow/ take Blender's fixtures from blender_fixtures.py."""

import os
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))
_CACHE = tempfile.mkdtemp(prefix="ctlab-test-cache-")
os.environ.setdefault("CTLAB_CACHE", _CACHE)
os.environ.setdefault("XDG_CACHE_HOME", _CACHE)
