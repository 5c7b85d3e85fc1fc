"""Where the project's own files are, and the one way it writes a file or a folder: whole or
not at all. Every write goes to a temporary sibling whose name is unique to the process and
the call, and is renamed over the target only when complete; a failure or an interrupt
removes the temporary and leaves the target as it was."""

from __future__ import annotations

import contextlib
import json
import math
import os
import re
import secrets
import shutil
import tempfile
from pathlib import Path

from .errors import UserError

PACKAGE_ROOT = Path(__file__).resolve().parents[2]      # the extension / repository root
OSL_DIR = PACKAGE_ROOT / "osl"
NODE_GROUPS_DIR = PACKAGE_ROOT / "node_groups"
DATA_DIR = PACKAGE_ROOT / "addon" / "data"               # tables shipped with the extension

# The temporaries being written now, which an exit that cannot unwind (a signal during a
# render, jobs/signals.py) removes; and their names: .NAME.<pid>-<random>.partial[.EXT]
_live: set = set()
_STAGING = re.compile(r"^\..+\.(\d+)-[0-9a-f]{8}\.partial(\.[^.]+)?$")


def _token() -> str:
    return f"{os.getpid()}-{secrets.token_hex(4)}"


def live_temporaries() -> list:
    return list(_live)


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:
        return True                      # another user's process
    return True


def remove_stale_temporaries(folder: Path) -> int:
    """Remove the temporaries in ``folder`` left by processes that no longer run (a killed
    bake's staging folder, say); returns how many."""
    removed = 0
    try:
        entries = list(Path(folder).iterdir())
    except OSError:
        return 0
    for entry in entries:
        m = _STAGING.match(entry.name)
        if m and int(m[1]) != os.getpid() and not _alive(int(m[1])):
            if entry.is_dir():
                shutil.rmtree(entry, ignore_errors=True)
            else:
                with contextlib.suppress(OSError):
                    entry.unlink()
            removed += 1
    return removed


def refuse_overwrite(inputs, outputs) -> None:
    """A job never writes over one of its own inputs (an HDRI named render.exr in --out)."""
    for out in outputs:
        out = Path(out)
        if not out.exists():
            continue
        for inp in inputs:
            if inp and Path(inp).exists() and os.path.samefile(out, inp):
                raise UserError(f"{out} is an input of this job ({inp}); writing there would "
                                "destroy it; choose another --out")


def staging_name(path: Path) -> Path:
    """A hidden sibling of ``path`` unique to this call, keeping its extension (image writers
    choose the format by it): .NAME.<pid>-<random>.partial.EXT"""
    path = Path(path)
    return path.with_name(f".{path.stem}.{_token()}.partial{path.suffix}")


@contextlib.contextmanager
def atomic_paths(*paths):
    """Yield temporary paths for ``paths``; when the block ends without error every one must
    exist and all are renamed into place, else none is."""
    staged = [staging_name(p) for p in paths]
    _live.update(staged)
    try:
        yield staged
        for tmp, final in zip(staged, paths):
            if not tmp.is_file():
                raise UserError(f"{final.name} was not written into {final.parent}")
        for tmp, final in zip(staged, paths):
            os.replace(tmp, final)
    finally:
        for tmp in staged:
            with contextlib.suppress(OSError):
                tmp.unlink()
        _live.difference_update(staged)


@contextlib.contextmanager
def atomic_path(path: Path):
    """Yield one temporary path for ``path`` (atomic_paths)."""
    with atomic_paths(Path(path)) as (tmp,):
        yield tmp


def write_text(path: Path, text: str) -> None:
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")


def finite_json(data):
    """``data`` with every NaN or infinity replaced by None (standard JSON has neither)."""
    if isinstance(data, float):
        return data if math.isfinite(data) else None
    if isinstance(data, dict):
        return {k: finite_json(v) for k, v in data.items()}
    if isinstance(data, (list, tuple)):
        return [finite_json(v) for v in data]
    return data


def json_text(data) -> str:
    """Standard JSON: NaN and infinities become null."""
    return json.dumps(finite_json(data), indent=2, allow_nan=False)


def write_json(path: Path, data) -> None:
    """Standard JSON (json_text), whole or not at all."""
    write_text(path, json_text(data))


def copy_file(src: Path, dst: Path) -> None:
    with atomic_path(dst) as tmp:
        shutil.copyfile(src, tmp)


def atomic_folder(final: Path, fill) -> None:
    """Run fill(staging) in a new hidden sibling folder and rename it to ``final``. When
    another process finished the same folder first, theirs is kept."""
    final = Path(final)
    staging = final.with_name(f".{final.name}.{_token()}.partial")
    remove_stale_temporaries(final.parent)
    staging.mkdir(parents=True)
    _live.add(staging)
    try:
        fill(staging)
        try:
            staging.rename(final)
        except OSError:
            if not final.is_dir():
                raise
    finally:
        shutil.rmtree(staging, ignore_errors=True)
        _live.discard(staging)


def check_writable(out_dir: Path) -> Path:
    """Create the output folder if needed and prove it is writable, before any work."""
    out_dir = Path(out_dir)
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=out_dir, prefix=".ctlab-probe-"):
            pass
    except OSError as exc:
        raise UserError(f"output folder not writable: {out_dir} ({exc.strerror or exc}); "
                        "choose another --out") from None
    return out_dir
