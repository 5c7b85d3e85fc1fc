"""Where the project's own files are, and the one way it writes a file or a folder: whole or
not at all. Every write goes to a temporary sibling whose name is unique to the process and
the call, and is renamed over the target only when complete; a failure or an interrupt
removes the temporary and leaves the target as it was."""

from __future__ import annotations

import contextlib
import json
import os
import secrets
import shutil
import tempfile
from pathlib import Path

from .errors import UserError

PACKAGE_ROOT = Path(__file__).resolve().parents[2]      # the extension / repository root
OSL_DIR = PACKAGE_ROOT / "osl"
NODE_GROUPS_DIR = PACKAGE_ROOT / "node_groups"


def _token() -> str:
    return f"{os.getpid()}-{secrets.token_hex(4)}"


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


@contextlib.contextmanager
def atomic_path(path: Path):
    """Yield one temporary path for ``path`` (atomic_paths)."""
    with atomic_paths(Path(path)) as (tmp,):
        yield tmp


def write_text(path: Path, text: str) -> None:
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")


def write_json(path: Path, data) -> None:
    write_text(path, json.dumps(data, indent=2))


def copy_file(src: Path, dst: Path) -> None:
    with atomic_path(dst) as tmp:
        shutil.copyfile(src, tmp)


def atomic_folder(final: Path, fill) -> None:
    """Run fill(staging) in a new hidden sibling folder and rename it to ``final``. When
    another process finished the same folder first, theirs is kept."""
    final = Path(final)
    staging = final.with_name(f".{final.name}.{_token()}.partial")
    staging.mkdir(parents=True)
    try:
        fill(staging)
        try:
            staging.rename(final)
        except OSError:
            if not final.is_dir():
                raise
    finally:
        shutil.rmtree(staging, ignore_errors=True)


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
