"""The one gate every path the program reads or writes passes (docs/bad-input.md, "Paths"):
the HDRI, the lights file, the .blend, the compared folders' files, --out and the cache.

- A path is made absolute and normalised before Blender sees it. Forms Blender reads
  otherwise than Python are refused: ``//`` at the start is relative to the open .blend
  (``BLI_path_abs``), and a backslash is a folder separator to Blender's path functions on
  every platform (``BLI_path_slash_native``).
- Byte limits: a name of at most 255 bytes (NAME_MAX of Linux and macOS file systems) and a
  whole path below Blender's FILE_MAX (1024 bytes with the NUL; ``BLI_path_utils.hh``), past
  which its image writer truncates a path silently and writes elsewhere (measured on bpy
  5.2.3: ``Image.save_render`` to a path of 1030 bytes wrote the file at its first 1023). An
  output folder keeps ``OUTPUT_RESERVE`` bytes for the longest name a job writes below it (a
  staging name of a matrix sub-folder's file, ``core.files.staging_name``). Checked before any work.
- An input is a regular file: stat first, then opened with O_NONBLOCK, so a named pipe or a
  device is refused and never blocks (open(2): "O_NONBLOCK ... for a FIFO, open returns
  immediately").
- Inputs may not be at, under or over an output; no output lies inside the cache (which
  ctlab rebuilds and removes entries of), and the cache lies inside no output.
- A name derived from a user's file (a lights file's stem as a parity folder) is reduced to
  a safe single name that cannot leave its folder (``safe_name``).
"""

from __future__ import annotations

import os
import re
import stat
from pathlib import Path

from .errors import UserError

MAX_NAME_BYTES = 255
FILE_MAX = 1024  # Blender's path buffer, NUL included
MAX_PATH_BYTES = 1000  # a margin below FILE_MAX for every path handed over
OUTPUT_RESERVE = 160  # below --out: "compare_split_sum_corrected/.render.…"

_KINDS = (
    (stat.S_ISDIR, "a folder"),
    (stat.S_ISFIFO, "a named pipe (FIFO)"),
    (stat.S_ISCHR, "a device"),
    (stat.S_ISBLK, "a device"),
    (stat.S_ISSOCK, "a socket"),
)


def _short(text: str) -> str:
    return text if len(text) <= 80 else text[:60] + "..."


def clean(text, what: str, output: bool = False) -> Path:
    """``text`` as an absolute, normalised path, or a UserError naming ``what``. ``output``:
    a folder the job writes below (OUTPUT_RESERVE bytes are kept for its names)."""
    text = os.fspath(text) if not isinstance(text, str) else text
    if not text or not text.strip():
        raise UserError(f"empty {what}; give a folder or file name")
    if "\0" in text:
        raise UserError(f"{what} holds a NUL character: {_short(text)!r}")
    if text.startswith("//"):
        raise UserError(
            f"{what} {_short(text)!r} starts with '//', which Blender reads as "
            "relative to the open .blend file; give a plain path"
        )
    if "\\" in text:
        raise UserError(
            f"{what} {_short(text)!r} holds a backslash, which Blender reads as a "
            "folder separator; rename it or give another path"
        )
    try:
        encoded = os.fsencode(text)
    except UnicodeError:
        raise UserError(f"{what} {_short(text)!r} cannot be encoded for this file system") from None
    if any(len(part) > MAX_NAME_BYTES for part in encoded.split(b"/")):
        raise UserError(
            f"{what} is longer than this system allows: a name of over "
            f"{MAX_NAME_BYTES} bytes in {_short(text)}"
        )
    path = os.path.abspath(text)
    limit = MAX_PATH_BYTES - (OUTPUT_RESERVE if output else 0)
    if len(os.fsencode(path)) > limit:
        raise UserError(
            f"{what} is longer than this system allows: {len(os.fsencode(path))} "
            f"bytes over {limit} (Blender writes paths of at most {FILE_MAX - 1}"
            f"{' with the names ctlab writes below it' if output else ''}): "
            f"{_short(path)}"
        )
    return Path(path)


def kind(mode: int) -> str | None:
    """What a file of this mode is when it is not a regular file (None for one)."""
    return next(
        (name for test, name in _KINDS if test(mode)),
        None if stat.S_ISREG(mode) else "not a regular file",
    )


def input_file(text, what: str, missing: str | None = None) -> Path:
    """An existing regular file to read (clean, stat, then opened without blocking); a
    UserError ``missing`` (default "WHAT not found: PATH") when there is none."""
    path = clean(text, what)
    try:
        st = os.stat(path)
    except FileNotFoundError:
        raise UserError(missing or f"{what} not found: {path}") from None
    except OSError as exc:
        raise UserError(f"{what} {path} cannot be read ({exc.strerror or exc})") from None
    if kind(st.st_mode):
        raise UserError(f"{what} {path} is {kind(st.st_mode)}, not a regular file; give a file")
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
    except OSError as exc:
        raise UserError(f"{what} {path} cannot be read ({exc.strerror or exc})") from None
    try:
        if kind(os.fstat(fd).st_mode):  # replaced between the stat and the open
            raise UserError(f"{what} {path} is not a regular file; give a file")
    finally:
        os.close(fd)
    return path


def read_bytes(path, what: str, missing: str | None = None) -> bytes:
    """The bytes of an input file (input_file), read from the descriptor that was checked."""
    path = input_file(path, what, missing)
    fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
    try:
        if kind(os.fstat(fd).st_mode):
            raise UserError(f"{what} {path} is not a regular file; give a file")
        chunks = []
        while chunk := os.read(fd, 1 << 20):
            chunks.append(chunk)
        return b"".join(chunks)
    except OSError as exc:
        raise UserError(f"{what} {path} cannot be read ({exc.strerror or exc})") from None
    finally:
        os.close(fd)


def _real(path) -> Path:
    return Path(os.path.realpath(path))


def _at_or_under(a: Path, b: Path) -> bool:
    return a == b or b in a.parents


def _same(a: Path, b: Path) -> bool:
    try:
        return os.path.samefile(a, b)
    except OSError:
        return False


def check_job(inputs=(), outputs=(), folders=(), cache=None) -> None:
    """Before any work: no input at, under or over an output (``outputs``: files the job
    writes; ``folders``: the folders it writes below); a folder or other non-file where an
    output file goes is refused; no output inside ``cache`` and ``cache`` inside no output
    file."""
    inputs = [Path(i) for i in inputs if i]
    outputs = [Path(o) for o in outputs]
    for out in outputs:
        try:
            mode = os.lstat(out).st_mode
        except OSError:
            continue
        if not stat.S_ISLNK(mode) and kind(mode):
            raise UserError(
                f"{out} is {kind(mode)} where this job writes a file; move it "
                "away or choose another --out"
            )
    for inp in inputs:
        ri = _real(inp)
        for out in outputs:
            ro = _real(out)
            if ri == ro or _same(inp, out):
                raise UserError(
                    f"{out} is an input of this job ({inp}); writing there would "
                    "destroy it; choose another --out"
                )
            if _at_or_under(ri, ro) or _at_or_under(ro, ri):
                where = (
                    f"inside {out}, which this job writes"
                    if _at_or_under(ri, ro)
                    else f"and this job writes {out} inside it"
                )
                raise UserError(f"{inp} is an input of this job {where}; choose another --out")
    if cache is not None:
        rc = _real(cache)
        for folder in [*folders, *outputs]:
            if _at_or_under(_real(folder), rc):
                raise UserError(
                    f"{folder} is inside the cache folder {cache}, whose entries "
                    "ctlab rebuilds and removes; choose another --out"
                )
        for out in outputs:
            if _at_or_under(rc, _real(out)):
                raise UserError(
                    f"the cache folder {cache} is where this job writes {out}; "
                    "choose another --out or set CTLAB_CACHE"
                )


_UNSAFE = re.compile(r"[^A-Za-z0-9._+-]+", re.ASCII)


def safe_name(text: str, default: str = "run", limit: int = 64) -> str:
    """A single folder name made from ``text`` (a user's file name): ASCII letters, digits
    and ``._+-`` only, no leading dot (so never ``.`` or ``..``), at most ``limit`` bytes."""
    name = _UNSAFE.sub("_", str(text)).lstrip(".")[:limit].rstrip(".")
    return name or default


_INT = re.compile(r"[+-]?[0-9]+", re.ASCII)
_FLOAT = re.compile(
    r"[+-]?(inf|infinity|nan|([0-9]+\.?[0-9]*|\.[0-9]+)(e[+-]?[0-9]+)?)", re.ASCII | re.IGNORECASE
)


def ascii_int(text) -> int:
    """An integer written with ASCII digits only (int() also takes '٣' and '1_0'; a '²',
    which str.isdigit accepts, it refuses)."""
    text = str(text).strip()
    if not _INT.fullmatch(text):
        raise ValueError(f"not an integer: {text!r}")
    return int(text)


def ascii_float(text) -> float:
    """A number written with ASCII digits only (float() also takes other scripts' digits and
    '1_0')."""
    text = str(text).strip()
    if not _FLOAT.fullmatch(text):
        raise ValueError(f"not a number: {text!r}")
    return float(text)


ascii_int.__name__ = "int"  # argparse: "invalid int value: '²'"
ascii_float.__name__ = "float"
