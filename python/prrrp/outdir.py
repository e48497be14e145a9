"""All-or-nothing output folders.

A command that writes a folder builds it aside, in a hidden sibling, and swaps it in with
one atomic rename (Linux `renameat2(RENAME_EXCHANGE)`; elsewhere two renames, repaired on
the next start if interrupted between them). A failed, interrupted or terminated run leaves
the old folder exactly as it was; leftovers of a run killed outright are removed the next
time a command writes beside them.

The folder belongs to prrrp: a marker file `.prrrp-output` is written in it, and an existing
folder is replaced only when it is empty or carries that marker, so that `--out .` or a
folder of someone else's files is never swapped away.
"""

from __future__ import annotations

import contextlib
import ctypes
import ctypes.util
import os
import shutil
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import TypeVar

MARKER = ".prrrp-output"
_T = TypeVar("_T")


class OutputDirError(ValueError):
    """The output folder cannot be written (it is a file, or holds foreign files)."""


def _prefixes(out: Path) -> tuple[str, str]:
    return f".{out.name}.prrrp-tmp-", f".{out.name}.prrrp-old-"


def _cleanup(out: Path) -> None:
    """Removes what a killed run left beside `out`, and restores `out` if a run died
    between the two renames of the fallback swap."""
    parent = out.parent
    tmp_prefix, old_prefix = _prefixes(out)
    with contextlib.suppress(OSError):
        for entry in parent.iterdir():
            if entry.name.startswith(old_prefix) and not out.exists():
                entry.rename(out)
            elif entry.name.startswith((tmp_prefix, old_prefix)):
                shutil.rmtree(entry, ignore_errors=True)


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
    out = Path(out).absolute()
    out.parent.mkdir(parents=True, exist_ok=True)
    _cleanup(out)
    _check(out)
    tmp_prefix, old_prefix = _prefixes(out)
    tmp = Path(tempfile.mkdtemp(prefix=tmp_prefix, dir=out.parent))
    try:
        result = build(tmp)
        (tmp / MARKER).write_text("written by prrrp; this folder is replaced as a whole\n")
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
        if tmp.exists():
            shutil.rmtree(tmp, ignore_errors=True)
