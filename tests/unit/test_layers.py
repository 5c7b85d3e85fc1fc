"""The architecture, checked from the source: four layers that import only downward (core <
blender < jobs < ui), a core without Blender, no import cycle among the modules, and a
repository that cites its own documents (no path outside it, no issue numbers)."""

import ast
import re
from pathlib import Path


from helpers import ROOT

ADDON = ROOT / "addon"
LAYERS = ("core", "blender", "jobs", "ui")
BLENDER_MODULES = {"bpy", "mathutils", "bmesh", "gpu", "cycles", "bl_math", "addon_utils"}


def _modules():
    """{(layer, module): [(imported layer, imported module or None, line)]} from every import
    of every module, top-level or inside functions; a package's modules are named with dots
    (ui.operators.jobs), and a relative import is resolved from the module's own package."""
    graph = {}
    for layer in LAYERS:
        for path in sorted((ADDON / layer).rglob("*.py")):
            rel = path.relative_to(ADDON).with_suffix("").parts  # ("ui", "operators", "jobs")
            package = rel[:-1]  # ("ui", "operators")
            if rel[-1] == "__init__":
                rel = rel[:-1]
                package = rel
            if len(rel) < 2:
                continue  # the layer's __init__
            name = (layer, ".".join(rel[1:]))
            edges = graph.setdefault(name, [])
            for node in ast.walk(ast.parse(path.read_text(), str(path))):
                if isinstance(node, ast.ImportFrom) and node.level:
                    base = list(package[: len(package) - (node.level - 1)])
                    parts = (node.module or "").split(".") if node.module else []
                    target = base + parts
                    # "from ..blender import model_node": the names are the modules
                    targets = (
                        [target + [a.name] for a in node.names] if len(target) < 2 else [target]
                    )
                    for target in targets:
                        if len(target) < 2:  # the add-on's own package
                            continue
                        edges.append((target[0], _module_of(target), node.lineno))
                elif isinstance(node, ast.Import):
                    edges += [("external", a.name.split(".")[0], node.lineno) for a in node.names]
                elif isinstance(node, ast.ImportFrom):
                    edges.append(("external", (node.module or "").split(".")[0], node.lineno))
    return graph


def _module_of(target: list) -> str:
    """The module a dotted target names, within its layer: a package's module when the
    package is a folder (ui.operators.jobs), else the first name (core.model)."""
    layer, rest = target[0], target[1:]
    if (ADDON / layer / rest[0]).is_dir():
        if len(rest) > 1 and (ADDON / layer / rest[0] / f"{rest[1]}.py").is_file():
            return f"{rest[0]}.{rest[1]}"
        return rest[0]
    return rest[0]


GRAPH = _modules()


def test_every_module_lives_in_a_layer():
    loose = [p.name for p in ADDON.glob("*.py") if p.name != "__init__.py"]
    assert not loose, f"modules outside the four layers: {loose}"


def test_imports_only_go_down():
    rank = {layer: i for i, layer in enumerate(LAYERS)}
    upward = [
        f"{layer}.{mod}:{line} imports {tl}.{tm}"
        for (layer, mod), edges in GRAPH.items()
        for tl, tm, line in edges
        if tl in rank and rank[tl] > rank[layer]
    ]
    assert not upward, upward


def test_the_core_needs_no_blender():
    found = [
        f"core.{mod}:{line} imports {tm}"
        for (layer, mod), edges in GRAPH.items()
        if layer == "core"
        for tl, tm, line in edges
        if tl == "external" and tm in BLENDER_MODULES
    ]
    assert not found, found


def test_no_import_cycle():
    modules = {m for m in GRAPH}
    succ = {
        m: {(tl, tm) for tl, tm, _ in edges if (tl, tm) in modules and (tl, tm) != m}
        for m, edges in GRAPH.items()
    }
    state, path = {}, []

    def visit(m):
        state[m] = "open"
        path.append(m)
        for n in succ[m]:
            if state.get(n) == "open":
                cycle = path[path.index(n) :] + [n]
                raise AssertionError(" -> ".join(".".join(x) for x in cycle))
            if n not in state:
                visit(n)
        path.pop()
        state[m] = "done"

    for m in sorted(modules):
        if m not in state:
            visit(m)


def _repository_files():
    skip = {".git", ".venv", "out", "dist", "__pycache__", ".pytest_cache"}
    for path in ROOT.rglob("*"):
        rel = path.relative_to(ROOT)
        if (
            path.is_file()
            and not any(p in skip or p.startswith(".venv") for p in rel.parts)
            and path.suffix in (".py", ".osl", ".toml", ".md", ".sh", ".txt", "")
            and rel.parts[0] != ".git"
        ):
            yield rel, path


def test_the_repository_cites_only_itself():
    """Nothing names a folder outside the repository (the model is docs/model.md) or an
    issue of a tracker a clone does not have."""
    outside = re.compile(r"\bshared/|\bSPEC\.md\b")
    issue = re.compile(r"\b[Ii]ssues? #?\d+\b|\(#\d+\)")
    found = []
    for rel, path in _repository_files():
        if rel == Path("tests/unit/test_layers.py"):
            continue
        for n, line in enumerate(path.read_text(errors="replace").splitlines(), 1):
            if outside.search(line) or issue.search(line):
                found.append(f"{rel}:{n}: {line.strip()[:80]}")
    assert not found, "\n".join(found)


def test_the_unit_tier_needs_no_blender():
    """tests/unit runs without bpy (./scripts/test.sh --quick): no test there, and no module
    of the add-on they import, imports bpy or a layer above the core."""
    found = []
    for path in sorted((ROOT / "tests" / "unit").glob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            names = (
                [a.name for a in node.names]
                if isinstance(node, ast.Import)
                else [node.module or ""]
                if isinstance(node, ast.ImportFrom)
                else []
            )
            for name in names:
                top = name.split(".")
                if (
                    top[0] in BLENDER_MODULES
                    or (top[0] == "addon" and len(top) > 1 and top[1] in ("blender", "jobs", "ui"))
                    or name == "blender_fixtures"
                ):
                    found.append(f"{path.name}:{node.lineno} imports {name}")
    assert not found, found
