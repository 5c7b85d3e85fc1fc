"""The documentation is walkable and not stale: every relative link resolves, every file the
docs or the code's comments name exists, every module is named in docs/architecture.md, and
the README stays a front page that links each docs page."""

import re
from pathlib import Path

import pytest

from helpers import ROOT

DOCS = [ROOT / "README.md"] + sorted((ROOT / "docs").glob("*.md"))
LINK = re.compile(r"\]\(([^)#\s]+)(?:#[^)]*)?\)")
# a repository path: a top-level folder, then names, ending in a file's extension
REPO_PATH = re.compile(
    r"(?<![\w/.-])((?:addon|osl|node_groups|scripts|tests|bench|docs)"
    r"/[\w/*.-]*\.(?:py|osl|h|toml|sh|md|txt|json|npy|png))\b"
)
# a module named by its layer: core/settings.py, blender/node_group.py ...
LAYER_PATH = re.compile(r"(?<![\w/.-])((?:core|blender|jobs|ui)/\w+\.py)\b")
PLACEHOLDER = re.compile(r"/[A-Z]{3,}\.")  # tests/FILE.py, addon/data/NAME.npy
MODULES = sorted(p for p in (ROOT / "addon").glob("*/**/*.py") if p.stem != "__init__")


def _exists(name: str, base: Path) -> bool:
    if "*" in name:
        return any(base.glob(name))
    return (base / name).exists()


@pytest.mark.parametrize("page", DOCS, ids=lambda p: p.name)
def test_every_relative_link_resolves(page):
    text = page.read_text()
    broken = [
        target
        for target in LINK.findall(text)
        if "://" not in target and not (page.parent / target).exists()
    ]
    assert not broken, f"{page.name}: {broken}"


def _sources():
    for folder in ("addon", "scripts", "tests", "osl", "node_groups", ".ci"):
        for path in (ROOT / folder).rglob("*"):
            if (
                path.suffix in (".py", ".osl", ".h", ".toml", ".sh", "")
                and path.is_file()
                and "__pycache__" not in path.parts
            ):
                yield path
    yield from DOCS


def test_every_file_the_docs_and_comments_name_exists():
    stale = []
    for path in _sources():
        text = path.read_text(errors="replace")
        for name in REPO_PATH.findall(text):
            if not _exists(name, ROOT) and not PLACEHOLDER.search(name):
                stale.append(f"{path.relative_to(ROOT)}: {name}")
        for name in LAYER_PATH.findall(text):
            if not _exists(name, ROOT / "addon"):
                stale.append(f"{path.relative_to(ROOT)}: {name}")
    assert not stale, "\n".join(sorted(set(stale)))


def test_every_module_is_named_in_the_architecture():
    text = (ROOT / "docs" / "architecture.md").read_text()

    def named(p):
        if p.parent.parent.name != "addon":  # a package's module: by its path
            return f"{p.parent.name}/{p.name}" in text
        return f"`{p.stem}`" in text or f"{p.parent.name}/{p.name}" in text

    missing = [str(p.relative_to(ROOT)) for p in MODULES if not named(p)]
    assert not missing, missing


def test_the_readme_is_a_front_page():
    text = (ROOT / "README.md").read_text()
    assert len(text.encode()) < 8000
    for page in ("usage", "model", "fidelity", "architecture", "testing"):
        assert f"(docs/{page}.md)" in text, page
    # the two commands, as .ci/run and a fresh machine use them
    assert "./scripts/ctlab.sh matrix" in text and "./scripts/test.sh" in text


def test_the_longest_files_named_for_the_workers_exist():
    """tests/conftest.py hands the longest files to the workers first: a renamed or removed
    file would silently fall to the end of the queue."""
    import ast

    tests = ROOT / "tests"
    tree = ast.parse((tests / "conftest.py").read_text())
    (names,) = [
        ast.literal_eval(node.value)
        for node in tree.body
        if isinstance(node, ast.Assign) and getattr(node.targets[0], "id", "") == "LONGEST_FILES"
    ]
    assert len(names) > 10
    assert not [name for name in names if not (tests / name).is_file()]
