"""All-or-nothing output folders.

A command that writes a folder builds it aside, in a hidden sibling, and swaps it in with
one atomic rename (Linux `renameat2(RENAME_EXCHANGE)`; elsewhere two renames, repaired on
the next start if interrupted between them). A failed, interrupted or terminated run leaves
the old folder exactly as it was. Staging folders are locked (`flock`) while their run
lives, so that the next run removes only those of runs that died. An existing folder is
replaced only when it is empty or carries prrrp's marker `.prrrp-output`; a symbolic link
given as `--out` is kept and its target replaced; the folder gets ordinary `mkdir`
permissions.

Design: docs/design/output-folders.md.
"""

from __future__ import annotations

import contextlib
import ctypes
import ctypes.util
import os
import shutil
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import TypeVar

from prrrp import signals
from prrrp._prrrp import InvalidInputError

try:
    import fcntl
except ImportError:  # pragma: no cover - not on Linux/macOS
    fcntl = None  # type: ignore[assignment]

MARKER = ".prrrp-output"
#: A folder of the creation prefix younger than this (s) may belong to a run between
#: creating and locking its staging folder (microseconds): it is left alone.
STARTING_GRACE_S = 60.0
_T = TypeVar("_T")


class OutputDirError(InvalidInputError):
    """The output folder cannot be written (it is a file, or holds foreign files)."""


def _prefixes(out: Path) -> tuple[str, str]:
    return f".{out.name}.prrrp-tmp-", f".{out.name}.prrrp-old-"


def _new_prefix(out: Path) -> str:
    """Prefix of a staging folder in the instant between its creation and its lock; it is
    renamed to the staging prefix once locked, so that a staging folder is never seen
    unlocked while its run lives."""
    return f".{out.name}.prrrp-new-"


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def resolve(out: str | os.PathLike[str]) -> Path:
    """The folder that `out` names: absolute, with a symbolic link (or a chain of them)
    followed to its target, so that the target is replaced and the link kept."""
    path = Path(out).absolute()
    if path.is_symlink():
        return Path(os.path.realpath(path))
    return path


def _lock(path: Path) -> int | None:
    """An exclusive lock on the folder `path`, held until the returned descriptor is
    closed (or the process dies); None where the system has no flock."""
    if fcntl is None:
        return None
    fd = os.open(path, os.O_RDONLY)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        os.close(fd)
        raise
    return fd


def _younger_than(path: Path, seconds: float) -> bool:
    try:
        return time.time() - path.stat().st_mtime < seconds
    except OSError:
        return False


def _in_use(path: Path) -> bool:
    """Whether a live run holds the staging folder `path`."""
    if fcntl is None:
        # No locks to ask: only folders older than a day count as abandoned.
        return _younger_than(path, 86400.0)
    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError:
        return False
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        return True
    finally:
        os.close(fd)  # also releases the probe's lock
    return False


def _note(message: str) -> None:
    print(f"prrrp: {message}", file=sys.stderr)


def _cleanup(out: Path) -> list[str]:
    """Removes the staging folders of dead runs beside `out` (never a live run's), and
    restores `out` if a run died between the two renames of the fallback swap. Returns
    the names removed; says on stderr what it removed and which live runs it found."""
    parent = out.parent
    tmp_prefix, old_prefix = _prefixes(out)
    new_prefix = _new_prefix(out)
    removed: list[str] = []
    live: list[str] = []
    with contextlib.suppress(OSError):
        for entry in sorted(parent.iterdir()):
            if not entry.name.startswith((tmp_prefix, old_prefix, new_prefix)):
                continue
            if entry.name.startswith(new_prefix) and _younger_than(entry, STARTING_GRACE_S):
                continue
            if entry.name.startswith(old_prefix) and not out.exists():
                entry.rename(out)
                _note(f"restored {out} from {entry.name}, left by an interrupted run")
            elif entry.name.startswith(tmp_prefix) and _in_use(entry):
                live.append(entry.name)
            else:
                shutil.rmtree(entry, ignore_errors=True)
                removed.append(entry.name)
    if removed:
        _note(
            f"removed {len(removed)} staging folder(s) beside {out} left by a run that was "
            f"killed: {', '.join(removed)}"
        )
    if live:
        _note(
            f"another prrrp run is writing to {out} ({', '.join(live)}); the run that "
            "finishes last replaces the folder"
        )
    return removed


def _check(out: Path) -> None:
    if out.exists() and not out.is_dir():
        raise OutputDirError(f"--out {out} exists and is not a directory")
    if out.is_dir():
        entries = [e.name for e in out.iterdir()]
        if entries and MARKER not in entries:
            raise OutputDirError(
                f"--out {out} holds files prrrp did not write ({', '.join(sorted(entries)[:3])}"
                f"{', ...' if len(entries) > 3 else ''}); give a new or empty folder"
            )
    # The folder is built beside `out` and renamed into place: its nearest existing
    # ancestor must be a folder this process can write in, known before the work (it was
    # found at the end, in an error naming the hidden staging folder).
    where = out.parent
    while not where.exists() and where != where.parent:
        where = where.parent
    if not where.is_dir():
        raise OutputDirError(f"--out {out}: {where} is a file, not a folder")
    if not os.access(where, os.W_OK | os.X_OK):
        raise OutputDirError(
            f"--out {out}: cannot write in {where} (no permission, or a read-only file "
            "system); give a folder you can write in"
        )


def check(out: str | os.PathLike[str]) -> None:
    """Raises OutputDirError now if `out` could not be written (call it before hours of
    computation, not after)."""
    _check(resolve(out))


def _exchange(a: Path, b: Path) -> bool:
    """Atomically swaps two paths (Linux renameat2 with RENAME_EXCHANGE); False where the
    system cannot."""
    name = ctypes.util.find_library("c")
    if name is None:
        return False
    try:
        libc = ctypes.CDLL(name, use_errno=True)
        renameat2 = libc.renameat2
    except (OSError, AttributeError):
        return False
    at_fdcwd, rename_exchange = -100, 2
    rc = renameat2(at_fdcwd, os.fsencode(a), at_fdcwd, os.fsencode(b), rename_exchange)
    return rc == 0


def write_dir(out: str | os.PathLike[str], build: Callable[[Path], _T]) -> _T:
    """Calls `build(tmp)` to fill a fresh hidden folder beside `out`, then swaps it in as
    `out`. Returns what `build` returns. Raises OutputDirError for an unusable `out`, and
    whatever `build` raises (the old `out` is then untouched)."""
    out = resolve(out)
    _check(out)
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise OutputDirError(f"--out {out}: cannot create {out.parent} ({e.strerror})") from None
    _cleanup(out)
    _check(out)
    tmp_prefix, old_prefix = _prefixes(out)
    tmp, lock = None, None
    try:
        with signals.deferred():  # interrupted in here, the cleanup would miss the folder
            try:
                tmp = Path(tempfile.mkdtemp(prefix=_new_prefix(out), dir=out.parent))
            except OSError as e:
                raise OutputDirError(
                    f"--out {out}: cannot write in {out.parent} ({e.strerror})"
                ) from None
            lock = _lock(tmp)
            locked = tmp.with_name(tmp_prefix + tmp.name[len(_new_prefix(out)) :])
            tmp.rename(locked)
            tmp = locked
        # mkdtemp makes the folder private (0700); the output is an ordinary folder.
        os.chmod(tmp, 0o777 & ~_umask())
        result = build(tmp)
        (tmp / MARKER).write_text("written by prrrp; this folder is replaced as a whole\n")
        signals.checkpoint()  # a Ctrl-C Python dropped must not let the folder land
        if not out.exists():
            tmp.rename(out)
        elif _exchange(tmp, out):
            shutil.rmtree(tmp, ignore_errors=True)  # now the old folder
        else:
            old = Path(tempfile.mkdtemp(prefix=old_prefix, dir=out.parent))
            old.rmdir()
            out.rename(old)
            tmp.rename(out)
            shutil.rmtree(old, ignore_errors=True)
        return result
    finally:
        if tmp is not None and tmp.exists():
            shutil.rmtree(tmp, ignore_errors=True)
        if lock is not None:
            os.close(lock)
