"""The BRDF plots' evaluations kept in the cache (core/cache.py), so that a job run again with
the same switches, or several jobs of one session, render each plot once.

A plot's results (brdf_plot.assemble: the slice, the lobes and the directional albedos of
each variant, and the variants' labels) depend only on its PlotSettings, on the code that
renders and assembles them (the OSL shader, the node group's description, the add-on's Python)
and on Blender's version. The key is the SHA-256 of all of these, so that an edit of any of
them, or another Blender, renders again; an entry holds the results as one ``.npz`` (the
arrays, dtypes kept) with the labels, signed like every cache entry (a damaged one is rendered
again, never used)."""

from __future__ import annotations

import functools
import hashlib
import json
import zipfile
from dataclasses import asdict
from pathlib import Path

import bpy
import numpy as np

from ..core import cache
from ..core.files import NODE_GROUPS_DIR, OSL_DIR, PACKAGE_ROOT

VERSION = 2  # 2: the .npz holds an index of its arrays
RESULTS = "results.npz"
INDEX = "index"  # the .npz's index of its arrays (save)
SEPARATOR = "|"  # between the nested keys of an array's name in the .npz
_ADDON = PACKAGE_ROOT / "addon"  # the add-on's Python package


@functools.lru_cache(maxsize=1)
def _sources_digest() -> str:
    """SHA-256 of every file the plot's evaluation is made from: the add-on's Python, the
    OSL shader with its headers, the node group's description."""
    h = hashlib.sha256()
    files = (
        sorted(_ADDON.rglob("*.py"))
        + sorted(OSL_DIR.glob("*"))
        + sorted(NODE_GROUPS_DIR.glob("*.toml"))
    )
    for p in files:
        if p.is_file() and "__pycache__" not in p.parts:
            h.update(p.relative_to(PACKAGE_ROOT).as_posix().encode() + b"\0" + p.read_bytes())
    return h.hexdigest()


def key(settings) -> str:
    """The cache key of a plot's results."""
    what = json.dumps(
        {"settings": asdict(settings), "blender": bpy.app.version_string},
        sort_keys=True,
        default=list,
    )
    digest = hashlib.sha256(what.encode() + _sources_digest().encode()).hexdigest()
    return f"plot-v{VERSION}-{digest[:32]}"


def save(results: dict, path: Path) -> None:
    """The results (nested dicts of arrays, "labels" a dict of strings) as one .npz, with an
    index of its arrays (name, dtype, shape and a digest of the bytes) that load checks."""
    arrays = {k: v for k, v in results.items() if k != "labels"}
    flat = {}
    for tag, tree in arrays.items():
        for name, value in _leaves(tree):
            flat[SEPARATOR.join((tag, *name))] = np.asarray(value)
    flat["labels"] = np.frombuffer(json.dumps(results.get("labels", {})).encode(), np.uint8)
    index = {name: _describe(value) for name, value in flat.items()}
    flat[INDEX] = np.frombuffer(json.dumps(index, sort_keys=True).encode(), np.uint8)
    np.savez(Path(path), **flat)


def _describe(value: np.ndarray) -> list:
    value = np.ascontiguousarray(value)
    digest = hashlib.sha256(value.tobytes()).hexdigest()
    return [str(value.dtype), list(value.shape), digest]


def _leaves(tree, name=()):
    if isinstance(tree, dict):
        for k, v in tree.items():
            yield from _leaves(v, (*name, k))
    else:
        yield name, tree


def load(path: Path) -> dict:
    """The results that save() wrote; a ValueError when they are not whole (an array
    missing, added or changed against the index)."""
    results: dict = {}
    with np.load(path, allow_pickle=False) as data:
        index = json.loads(data[INDEX].tobytes().decode())
        arrays = {name: data[name] for name in data.files if name != INDEX}
        if not isinstance(index, dict) or {n: _describe(a) for n, a in arrays.items()} != index:
            raise ValueError(f"{path} does not match its index")
        for full, value in arrays.items():
            if full == "labels":
                results["labels"] = json.loads(value.tobytes().decode())
                continue
            tag, *name = full.split(SEPARATOR)
            node = results.setdefault(tag, {})
            for k in name[:-1]:
                node = node.setdefault(k, {})
            node[name[-1]] = value
    return results


def cached(settings, evaluate) -> dict:
    """The plot's results from the cache, else ``evaluate()``'s, then kept there. An entry
    whose manifest holds but whose results do not read back whole (re-signed by hand) is
    discarded and rendered again, never used."""
    k = key(settings)
    hit = cache.lookup(k)
    if hit is not None:
        try:
            return load(hit / RESULTS)
        except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile):
            cache.discard(hit)
    results = evaluate()
    cache.build(k, lambda stage: save(results, stage / RESULTS))
    return results
