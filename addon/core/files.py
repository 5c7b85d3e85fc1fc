"""Where the project's own files are, and the one way it writes a file or a folder: whole or
not at all. Every write goes to a temporary sibling whose name is unique to the process and
the call, and is renamed over the target only when complete and verified (its size, and a
read-back of an image's pixels or a JSON file's text: Blender's ``save_render`` reports no
failed write); a failure or an interrupt removes the temporary and leaves the target as it
was. A full disk, a file-size limit, a quota or a refused write (ENOSPC, EFBIG, EDQUOT,
EACCES, EROFS) is one line naming the file and the cause. Temporary folders (the OSL
compile's, the pixel grid's) are registered with the same cleanup (``temporary_folder``)."""

from __future__ import annotations

import contextlib
import errno
import json
import math
import os
import re
import secrets
import shutil
import tempfile
import time
from pathlib import Path

from .errors import UserError

PACKAGE_ROOT = Path(__file__).resolve().parents[2]  # the extension / repository root
OSL_DIR = PACKAGE_ROOT / "osl"
NODE_GROUPS_DIR = PACKAGE_ROOT / "node_groups"
DATA_DIR = PACKAGE_ROOT / "addon" / "data"  # tables shipped with the extension

# The temporaries being written now, which an exit that cannot unwind (a signal during a
# render, jobs/signals.py) removes; and their names: .NAME.<pid>-<random>.partial[.EXT]
_live: set = set()
_STAGING = re.compile(r"^\..+\.(\d+)-[0-9a-f]{8}\.partial(\.[^.]+)?$")
# temporary_folder's names in the system's temporary folder: ctlab-<what>-<pid>-<random>
_TEMP_FOLDER = re.compile(r"^ctlab-[a-z]+-(\d+)-[0-9a-f]{12}$")
# A dead process's temporary folder is removed once it is this old: /tmp may be shared with
# another PID namespace (a container), where a running process's pid can look dead here.
TEMP_FOLDER_STALE_SECONDS = 3600.0


def _token() -> str:
    return f"{os.getpid()}-{secrets.token_hex(4)}"


def live_temporaries() -> list:
    """The temporaries now being written (the signal watcher's thread reads this while the
    main thread may be changing it: a copy taken again if the set changed meanwhile)."""
    for _ in range(100):
        try:
            return list(_live)
        except RuntimeError:  # "Set changed size during iteration"
            continue
    return list(_live)


def sha256(path: Path) -> str:
    """The SHA-256 of a file's content (hex): the one content hash of the project (cache
    manifests, the plot's and the task graph's ownership records, HDRI keys)."""
    import hashlib

    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def process_alive(pid: int) -> bool:
    """Whether a process of this machine runs (another user's counts as running)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:
        return True  # another user's process
    return True


def remove_stale_temporaries(
    folder: Path, names=_STAGING, older_than: float = 0.0, folders_only: bool = False
) -> int:
    """Remove the temporaries in ``folder`` left by processes that no longer run (a killed
    bake's staging folder, say): the entries whose name ``names`` matches with the writer's
    pid as its first group, last changed at least ``older_than`` seconds ago (folders only,
    when asked); returns how many."""
    removed = 0
    try:
        entries = list(Path(folder).iterdir())
    except OSError:
        return 0
    now = time.time()
    for entry in entries:
        m = names.match(entry.name)
        if m and int(m[1]) != os.getpid() and not process_alive(int(m[1])):
            if folders_only and (entry.is_symlink() or not entry.is_dir()):
                continue
            with contextlib.suppress(OSError):
                if now - entry.lstat().st_mtime < older_than:
                    continue
            if entry.is_dir():
                shutil.rmtree(entry, ignore_errors=True)
            else:
                with contextlib.suppress(OSError):
                    entry.unlink()
            removed += 1
    return removed


REPORT_MARK = b"<title>Cook-Torrance Lab:"  # in the head of every report ctlab writes


def forget_report(path) -> bool:
    """Remove an earlier run's report (a job writes its own last, so that one stopped
    half-way leaves no report showing new images beside old numbers), but only when ctlab
    wrote it: a regular file whose head holds REPORT_MARK. Returns whether it was removed."""
    path = Path(path)
    try:
        if not path.is_file() or path.is_symlink():
            return False
        with open(path, "rb") as f:
            head = f.read(1024)
    except OSError:
        return False
    if REPORT_MARK not in head:
        return False
    path.unlink(missing_ok=True)
    return True


def refuse_overwrite(inputs, outputs, folders=()) -> None:
    """A job never writes over one of its own inputs (an HDRI named render.exr in --out), nor
    inside the cache, nor where a folder stands in an output file's place (core.paths)."""
    from .paths import check_job

    try:
        cache_folder = cache_locator() if cache_locator else None
    except UserError:
        cache_folder = None
    check_job(inputs, outputs, folders, cache_folder)


# The cache folder's location (core.cache installs it; files cannot import cache).
cache_locator = None


# The errors of a write that a user can remedy: each one line naming the file and the cause.
WRITE_ERRORS = {
    errno.ENOSPC: "the disk is full",
    errno.EFBIG: "a file-size limit was reached",
    errno.EDQUOT: "the disk quota is exceeded",
    errno.EACCES: "permission denied",
    errno.EPERM: "permission denied",
    errno.EROFS: "the file system is read-only",
    errno.EIO: "an input/output error",
}


def public(path) -> Path:
    """The path a user knows for a staged one (.NAME.<pid>-<hex>.partial.EXT -> NAME.EXT):
    a writer nested in a staged set names the file it stands for."""
    path = Path(path)
    while m := _STAGING.match(path.name):
        path = path.with_name(path.name[1 : m.start(1) - 1] + (m[2] or ""))
    return path


def write_error(exc: OSError, path) -> UserError | None:
    """The UserError for a failed write of ``path``, or None when it is not a user's problem."""
    cause = WRITE_ERRORS.get(exc.errno)
    if cause is None:
        return None
    path = public(path)
    return UserError(
        f"cannot write {path}: {cause} ({exc.strerror or exc}); nothing was "
        "kept; free space or choose another --out"
    )


_IMAGE_SUFFIXES = {".exr", ".png", ".hdr", ".tif", ".tiff", ".jpg"}


def verify(tmp: Path, final: Path) -> None:
    """A staged file is whole before it is renamed: a regular file of some bytes; an image
    read back whole (OpenImageIO, when importable), a JSON file parsed."""
    final = public(final)

    def fail(why):
        raise UserError(
            f"cannot write {final}: {why}; nothing was kept (the disk may be "
            "full or a file-size limit reached)"
        )

    try:
        st = os.lstat(tmp)
    except OSError:
        raise UserError(f"{final.name} was not written into {final.parent}") from None
    if not os.path.isfile(tmp):
        fail("not a file")
    if st.st_size == 0:
        fail("the file is empty")
    suffix = final.suffix.lower()
    if suffix in _IMAGE_SUFFIXES:
        try:
            import OpenImageIO  # noqa: F401  (Blender's, exposed by the Blender layer)
        except ImportError:
            return
        try:
            _read_any(tmp)
        except UserError as exc:
            fail(f"it reads back truncated or corrupt ({' '.join(str(exc).split())[:120]})")
    elif suffix == ".json":
        try:
            json.loads(Path(tmp).read_text(encoding="utf-8"))
        except (OSError, ValueError) as exc:
            fail(f"it reads back as invalid JSON ({exc})")


@contextlib.contextmanager
def _quiet_stderr():
    """OpenEXR's core library prints its own line for a damaged file on the process's
    stderr; the read-back's failure is reported as one UserError instead."""
    try:
        saved = os.dup(2)
        null = os.open(os.devnull, os.O_WRONLY)
    except OSError:
        yield
        return
    os.dup2(null, 2)
    try:
        yield
    finally:
        os.dup2(saved, 2)
        os.close(saved)
        os.close(null)


def _read_any(path) -> None:
    with _quiet_stderr():
        _read_all(path)


def _read_all(path) -> None:
    import OpenImageIO as OIIO

    inp = OIIO.ImageInput.open(str(path))
    if inp is None:
        raise UserError(OIIO.geterror().strip() or "unknown format")
    try:
        pixels = inp.read_image(OIIO.FLOAT)
        if pixels is None or inp.has_error:
            raise UserError(inp.geterror().strip() or "truncated")
    finally:
        inp.close()


def staging_name(path: Path) -> Path:
    """A hidden sibling of ``path`` unique to this call, keeping its extension (image writers
    choose the format by it): .NAME.<pid>-<random>.partial.EXT"""
    path = Path(path)
    return path.with_name(f".{path.stem}.{_token()}.partial{path.suffix}")


@contextlib.contextmanager
def atomic_paths(*paths):
    """Yield temporary paths for ``paths``; when the block ends without error every one must
    exist and all are renamed into place, else none is."""
    paths = [Path(p) for p in paths]
    staged = [staging_name(p) for p in paths]
    _live.update(staged)
    current = paths[0] if paths else None
    try:
        try:
            yield staged
            for tmp, final in zip(staged, paths):
                current = final
                verify(tmp, final)
            for tmp, final in zip(staged, paths):
                current = final
                os.replace(tmp, final)
        except OSError as exc:
            named = {str(t): f for t, f in zip(staged, paths)}.get(str(exc.filename), current)
            error = write_error(exc, named)
            if error is None:
                raise
            raise error from None
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


@contextlib.contextmanager
def temporary_folder(prefix: str):
    """A private folder in the system's temporary folder, registered with the cleanup of an
    interrupt (jobs/signals.py) and removed after the block. Its name holds this process's
    pid, so that those a killed process left (SIGKILL, a power cut: nothing ran to remove
    them) are removed by a later one once an hour old."""
    if not _TEMP_FOLDER.match(f"{prefix}0-{'0' * 12}"):
        raise ValueError(f"temporary folder prefix {prefix!r}: ctlab-<lower-case letters>-")
    parent = Path(tempfile.gettempdir())
    remove_stale_temporaries(parent, _TEMP_FOLDER, TEMP_FOLDER_STALE_SECONDS, folders_only=True)
    folder = parent / f"{prefix}{os.getpid()}-{secrets.token_hex(6)}"
    _live.add(folder)  # before it exists: a signal never misses it
    try:
        try:
            folder.mkdir(mode=0o700)
        except OSError as exc:
            cause = WRITE_ERRORS.get(exc.errno) or exc.strerror or str(exc)
            raise UserError(
                f"cannot make a temporary folder in {parent}: {cause}; free space there or "
                "set TMPDIR to another folder (nothing was written)"
            ) from None
        yield folder
    finally:
        shutil.rmtree(folder, ignore_errors=True)
        _live.discard(folder)


def atomic_folder(final: Path, fill) -> None:
    """Run fill(staging) in a new hidden sibling folder and rename it to ``final``. When
    another process finished the same folder first, theirs is kept."""
    final = Path(final)
    staging = final.with_name(f".{final.name}.{_token()}.partial")
    remove_stale_temporaries(final.parent)
    _live.add(staging)
    try:
        staging.mkdir(parents=True)
        fill(staging)
        try:
            staging.rename(final)
        except OSError:
            if not final.is_dir():
                raise
    except OSError as exc:
        error = write_error(exc, exc.filename or final)
        if error is None:
            raise
        raise error from None
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
        raise UserError(
            f"output folder not writable: {out_dir} ({exc.strerror or exc}); choose another --out"
        ) from None
    return out_dir


def probe_writable(folder: Path) -> str | None:
    """Why a folder cannot be written (the error's text), or None when a file can be made
    there (os.access is not enough: root, ACLs, read-only mounts)."""
    try:
        with tempfile.NamedTemporaryFile(dir=folder, prefix=".ctlab-probe-"):
            pass
    except OSError as exc:
        return exc.strerror or str(exc)
    return None
