"""The write gate of an output folder that is also the user's: an export folder, the travel
folder beside a saved .blend. ctlab replaces only what it wrote there.

The folder keeps an ownership record, ``RECORD``: each file ctlab wrote (its path inside the
folder) with the SHA-256 it had when written (core.files.sha256). Before the first byte is
written, every place a file will land is checked (``Gate.check``):

- each folder on the way to a file below the one the user chose is absent or a real folder:
  a link is refused, so nothing is written through it outside that folder;
- the file's place is empty, or holds a regular file whose content is the one the record
  names (ctlab wrote it and nobody changed it since); any other file, the user's, is refused
  in one line naming it, unless the user asked to overwrite (``force``: ``--force``, the
  Overwrite box), which still replaces only a regular file, never a link or a folder;
- each name is one within the file system's limits (255 bytes with the staging name's
  additions, valid in its encoding), and no two differ by case alone;
- no input is an output (core.files.refuse_overwrite).

Then every file is staged and renamed into place together (core.files.atomic_paths: whole or
none; a failure or a cancel removes the staged files and any folder the gate made), and the
record is updated after the renames: a process killed in between leaves files the record does
not list, which a later run refuses rather than replaces, the safe side. An OSError becomes
one line naming the path that failed, the output's or, while reading, the input's.

The places themselves (``owned_folder``, ``owned_file``: absent, a real folder, a regular file
ctlab recognises) are the job folders' too: core/jobgraph/ownership.py recognises their files
by content (markers, logs, the plan) instead of a record. The cache has its manifests
(core/cache.py)."""

from __future__ import annotations

import contextlib
import json
import os
import stat
from pathlib import Path

from . import files
from .errors import UserError
from .paths import MAX_NAME_BYTES, kind

RECORD = ".ctlab-written.json"
_MARK = "Cook-Torrance Lab ownership record"


def _record_ok(data) -> bool:
    return (
        isinstance(data, dict)
        and data.get("written_by") == _MARK
        and isinstance(data.get("files"), dict)
        and all(isinstance(k, str) and isinstance(v, str) for k, v in data["files"].items())
    )


# --- places ctlab writes: absent, or what it wrote there, reached through real folders


def describe(mode: int) -> str:
    """What a file of this (lstat) mode is, with its article: "a link", "a folder", ..."""
    return "a link" if stat.S_ISLNK(mode) else kind(mode) or "a file"


@contextlib.contextmanager
def os_errors(path):
    """Any OSError in the block as one UserError line naming the file (core.files'
    WRITE_ERRORS for the causes a user can remedy)."""
    try:
        yield
    except OSError as exc:
        name = exc.filename or path
        cause = files.WRITE_ERRORS.get(exc.errno) or exc.strerror or str(exc)
        raise UserError(f"cannot use {name}: {cause}; nothing was changed there") from None


def lstat(path: Path):
    """``os.lstat(path)``, or None when nothing stands there; a path below a file or one that
    cannot be examined is one UserError line."""
    try:
        return os.lstat(path)
    except FileNotFoundError:
        return None
    except NotADirectoryError:
        raise UserError(f"{path} lies below a file; move it away or choose another --out") from None
    except OSError as exc:
        raise UserError(f"cannot use {path}: {exc.strerror or exc}") from None


def owned_folder(path: Path, what: str) -> None:
    """``path``, where ctlab keeps ``what``, is absent or a real folder (not a link to one:
    ctlab would write into a folder it did not choose); else one UserError line."""
    st = lstat(Path(path))
    if st is not None and (stat.S_ISLNK(st.st_mode) or not stat.S_ISDIR(st.st_mode)):
        raise UserError(
            f"{path} is {describe(st.st_mode)} where ctlab keeps {what}; "
            "move it away (nothing was written)"
        )


def owned_file(path: Path, what: str, ours=None) -> None:
    """``path``, where ctlab writes ``what``, is absent, or a regular file (not a link) that
    ``ours(path)`` says ctlab wrote (None: any regular file, an output of the job itself);
    a user's file, a link, a folder or a pipe is refused in one line before anything is
    written, so it is never replaced or removed."""
    st = lstat(Path(path))
    if st is None:
        return
    if not stat.S_ISREG(st.st_mode):
        raise UserError(
            f"{path} is {describe(st.st_mode)} where ctlab writes {what}; move it "
            "away (nothing was written)"
        )
    if ours is not None and not ours(Path(path)):
        raise UserError(
            f"{path} is a file ctlab did not write, where it writes {what}; move it "
            "away (nothing was written)"
        )


# A staged file's name adds ".", ".<pid>-<8 hex>.partial" to its own (core.files.staging_name)
STAGING_RESERVE = 32
MAX_OUTPUT_NAME_BYTES = MAX_NAME_BYTES - STAGING_RESERVE


def check_name(name: str, what: str, limit: int = MAX_OUTPUT_NAME_BYTES) -> None:
    """A name the file system takes, staged too: at most ``limit`` bytes (255 less the staging
    name's additions), valid in its encoding (a name read from a non-UTF-8 file name holds
    surrogates), no separator or NUL, not . or .."""
    try:
        size = len(os.fsencode(name))
        name.encode("utf-8")
    except UnicodeError:
        raise UserError(f"{what} {name!r} is not a valid file name (undecodable bytes)") from None
    if size > limit or not name or name in (".", "..") or "/" in name or "\0" in name:
        raise UserError(f"{what} {name[:60]!r} is not a valid file name (at most {limit} bytes)")


class Gate:
    """The output folder ``root``, where ctlab writes ``what`` (``force``: the user's files
    of the same names may be replaced)."""

    def __init__(self, root: Path, what: str, force: bool = False):
        self.root = Path(root)
        self.what = what
        self.force = force
        self._record: dict | None = None

    # --- the record ------------------------------------------------------------------
    def record(self) -> dict:
        """The files ctlab wrote here (relative path -> sha256); {} without a record. A file
        in the record's place that is not one is refused (it is the user's)."""
        if self._record is None:
            path = self.root / RECORD
            st = lstat(path)
            if st is None:
                self._record = {}
            else:
                try:
                    if not stat.S_ISREG(st.st_mode):
                        raise ValueError
                    fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK)
                    with os.fdopen(fd, "rb") as f:
                        data = json.loads(f.read(1 << 24).decode("utf-8"))
                except (OSError, ValueError):
                    data = None
                if not _record_ok(data):
                    raise UserError(
                        f"{path} is not ctlab's record of the files it wrote there; move it "
                        "away or choose another folder (nothing was written)"
                    )
                self._record = dict(data["files"])
        return self._record

    def ours(self, rel: str) -> bool:
        """Whether the file at ``rel`` is one ctlab wrote and nobody changed."""
        recorded = self.record().get(rel)
        if recorded is None:
            return False
        try:
            return files.sha256(self.root / rel) == recorded
        except OSError:
            return False

    # --- checks ------------------------------------------------------------------------
    def check(self, rels, inputs=()) -> None:
        """Before any byte is written: each ``rels`` (paths inside the folder) may be
        written (the module's rules); the inputs are no outputs."""
        if self.root.exists() and not self.root.is_dir():  # the folder the user named: a
            self._folder(self.root)  # link to a folder is the user's choice, below it none
        rels = list(rels)
        for rel in rels:
            parts = Path(rel).parts
            if not parts or Path(rel).is_absolute() or ".." in parts or Path(rel).as_posix() != rel:
                raise ValueError(f"{rel!r} is not a path inside the folder")
            for part in parts:
                check_name(part, "the output name")
            if rel == RECORD:
                raise UserError(f"an output may not be named {RECORD} (ctlab's record); rename it")
        files.refuse_overwrite(list(inputs), [self.root / r for r in rels] + [self.root / RECORD])
        seen = set()
        for rel in rels:
            parts = Path(rel).parts
            key = rel.casefold()  # one file where the file system folds case (macOS, Windows)
            if key in seen:
                raise UserError(f"two outputs would share {self.root / rel}; rename one")
            seen.add(key)
            where = self.root
            for part in parts[:-1]:
                where = where / part
                self._folder(where)
            self._file(rel)
        self.record()  # a foreign file in the record's place is refused now

    def _folder(self, path: Path) -> None:
        owned_folder(path, self.what)

    def _file(self, rel: str) -> None:
        """The place of ``rel`` is free, or holds ctlab's unchanged file (the record), or
        the user's regular file and ``force``; a link, a folder or a pipe never."""
        path = self.root / rel
        owned_file(path, self.what)
        if path.exists() and not self.force and not self.ours(rel):
            raise UserError(
                f"{path} is a file ctlab did not write (or one changed since); it was left "
                "alone: move it away, choose another folder, or overwrite it (--force, the "
                "Overwrite option)"
            )

    # --- writing -----------------------------------------------------------------------
    def write(self, writers: dict, inputs=()) -> list:
        """Write every file of ``writers`` (relative path -> writer(staged path)) whole and
        together, after the checks; returns the paths written."""
        rels = list(writers)
        self.check(rels, inputs)
        made = []
        try:
            for rel in rels:
                made += self._make_folders(Path(rel).parent)
            targets = [self.root / rel for rel in rels]
            with files.atomic_paths(*targets) as staged:
                for rel, tmp in zip(rels, staged):
                    writers[rel](Path(tmp))
            made = []
            record = dict(self.record())
            for rel, path in zip(rels, targets):
                record[rel] = files.sha256(path)
            files.write_json(self.root / RECORD, {"written_by": _MARK, "files": record})
            self._record = record
        except OSError as exc:
            raise _os_error(exc, self.root) from None
        finally:
            for folder in reversed(made):  # those the gate made, when nothing landed
                with contextlib.suppress(OSError):
                    folder.rmdir()
        return targets

    def _make_folders(self, rel_parent: Path) -> list:
        """Make the folder and those on the way to ``rel_parent`` inside it; the ones made."""
        made = []
        chain = [
            self.root.joinpath(*rel_parent.parts[: i + 1]) for i in range(len(rel_parent.parts))
        ]
        if lstat(self.root) is None:
            self.root.mkdir(parents=True)
            made.append(self.root)
        for where in chain:
            if lstat(where) is None:
                where.mkdir()
                made.append(where)
            self._folder(where)
        return made


def _os_error(exc: OSError, root: Path) -> UserError:
    """One line for an OSError while writing into ``root``, naming the path it names."""
    error = files.write_error(exc, exc.filename or root)
    if error is not None:
        return error
    name = files.public(exc.filename) if exc.filename else root
    return UserError(f"cannot write {name}: {exc.strerror or exc}; nothing was kept")


def read_input(path: Path, what: str, read):
    """``read(path)`` of an input, an OSError as one line naming the input (not an output)."""
    try:
        return read(path)
    except OSError as exc:
        raise UserError(f"cannot read {what} {path}: {exc.strerror or exc}") from None
