"""The OSL shader's source as Cycles is given it: osl/cook_torrance.osl with its parts
(osl/ct_*.h) inlined. Cycles compiles an internal script from a temporary copy, beside which
no included file would be found, so the add-on inlines every local include itself; the
standard headers (stdcycles.h) are left to the compiler. Pure Python: the tests read the
shader's text through here without Blender."""

from __future__ import annotations

import re
from pathlib import Path

from .errors import UserError
from .files import OSL_DIR

SHADER_FILE = OSL_DIR / "cook_torrance.osl"

# A local include: #include "name.osl" (or .h), a file beside the includer or in osl/.
_LOCAL_INCLUDE = re.compile(r'^#include "([\w.-]+)"[ \t]*$', re.M)


def parts(path: Path = SHADER_FILE) -> list:
    """The local files a shader includes, in order (each once)."""
    found = []
    for m in _LOCAL_INCLUDE.finditer(Path(path).read_text(encoding="utf-8")):
        for folder in (Path(path).parent, OSL_DIR):
            if (folder / m[1]).is_file():
                found.append(folder / m[1])
                break
    return found


def source(path: Path = SHADER_FILE, _depth: int = 0) -> str:
    """A shader's source with its local includes inlined (nested up to four deep)."""
    path = Path(path)
    if _depth > 4:
        raise UserError(f"{path.name}: includes nested too deep")

    def inline(m):
        for folder in (path.parent, OSL_DIR):
            if (folder / m[1]).is_file():
                return source(folder / m[1], _depth + 1)
        return m[0]

    return _LOCAL_INCLUDE.sub(inline, path.read_text(encoding="utf-8"))
