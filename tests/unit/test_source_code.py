"""core/source_code.py: a module's code as the shipped node group's digest hashes it. A
comment or a docstring edited leaves it; a change of code, even of one string value, does
not."""

import textwrap

from addon.core.source_code import code_bytes

BASE = textwrap.dedent('''
    """Module doc."""
    X = "kept"  # a comment


    def f(a):
        """Function doc,
        two lines."""
        return a + 1  # more


    class C:
        """Class doc."""

        y = f"{X}!"
''')


def _code(tmp_path, text, name="m.py"):
    path = tmp_path / name
    path.write_text(text)
    return code_bytes(path)


def test_comments_and_docstrings_do_not_count(tmp_path):
    base = _code(tmp_path, BASE)
    edited = BASE.replace("Module doc.", "Another text").replace("# a comment", "# changed")
    edited = edited.replace('"""Class doc."""', "'''Class\n    docs'''") + "\n# tail\n\n"
    assert _code(tmp_path, edited, "n.py") == base
    assert b"doc" not in base and b"comment" not in base


def test_code_counts(tmp_path):
    base = _code(tmp_path, BASE)
    for old, new in (("a + 1", "a + 2"), ('"kept"', '"kept!"'), ("!", "?"), ("def f", "def g")):
        assert _code(tmp_path, BASE.replace(old, new), "n.py") != base, (old, new)
