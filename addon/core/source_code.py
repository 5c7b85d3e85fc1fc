"""A Python module's code as a cache key hashes it: its text without comments, docstrings,
blank lines and trailing spaces, so that a comment or a docstring edited does not make a
built thing stale (the shipped node group: blender/node_group.py ``source_digest``). Read
with the tokenizer, whose comments and strings every supported Python reads alike (3.11 for
Blender 4.5, 3.13 for 5.2): the same file gives the same bytes on both."""

from __future__ import annotations

import io
import tokenize
from pathlib import Path


def code_bytes(path: Path) -> bytes:
    """The module's code: comments and statements that are only a string (docstrings)
    removed, then blank lines and trailing spaces."""
    source = Path(path).read_text(encoding="utf-8")
    spans, statement = [], []
    for tok in tokenize.generate_tokens(io.StringIO(source).readline):
        if tok.type == tokenize.COMMENT:
            spans.append((tok.start, tok.end))
        elif tok.type in (tokenize.NEWLINE, tokenize.ENDMARKER):
            if statement and all(t.type == tokenize.STRING for t in statement):
                spans.append((statement[0].start, statement[-1].end))
            statement = []
        elif tok.type not in (tokenize.NL, tokenize.INDENT, tokenize.DEDENT):
            statement.append(tok)
    lines = source.splitlines()
    for (r0, c0), (r1, c1) in sorted(spans, reverse=True):
        lines[r0 - 1 : r1] = [lines[r0 - 1][:c0] + lines[r1 - 1][c1:]]
    return "\n".join(line.rstrip() for line in lines if line.strip()).encode()
