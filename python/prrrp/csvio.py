"""Measurement files of the ``prrrp`` command line, and safe writing of output files.

CSV format (comma-separated, one header line, then one row per sample):

- ``t``: time, s, strictly increasing (uniform sampling for the preprocessing, e.g. 0.02 s);
- ``q1..q5``: joint positions [d1, θ2, θ3, θ4, d5] in m, rad, rad, rad, m;
- ``tau1..tau5``: generalised forces [F1, τ2, τ3, τ4, F5] in N, N·m, N·m, N·m, N;
- optional ``qd1..qd5`` (m/s, rad/s) and ``qdd1..qdd5`` (m/s², rad/s²): when both are given
  they are used as they are; otherwise velocities and accelerations are obtained by
  ``prrrp.preprocess`` (zero-phase low-pass filter and central differences).

Column order does not matter, names are case-insensitive, extra columns are an error (so a
misspelt name is not silently ignored). Lines starting with ``#`` are comments.
"""

from __future__ import annotations

import contextlib
import csv
import difflib
import math
import os
import tempfile
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np

NDOF = 5
POSITION_COLUMNS = tuple(f"q{i}" for i in range(1, NDOF + 1))
TORQUE_COLUMNS = tuple(f"tau{i}" for i in range(1, NDOF + 1))
VELOCITY_COLUMNS = tuple(f"qd{i}" for i in range(1, NDOF + 1))
ACCELERATION_COLUMNS = tuple(f"qdd{i}" for i in range(1, NDOF + 1))
REQUIRED_COLUMNS = ("t", *POSITION_COLUMNS, *TORQUE_COLUMNS)
OPTIONAL_COLUMNS = (*VELOCITY_COLUMNS, *ACCELERATION_COLUMNS)
ALL_COLUMNS = REQUIRED_COLUMNS + OPTIONAL_COLUMNS

#: Fewest samples accepted: the preprocessing trims the edges, and 8 parameters need many
#: more equations than unknowns to average the noise out.
MIN_SAMPLES = 20


class InputError(ValueError):
    """Bad input file: the message is one line saying what is wrong and where."""


def _expected() -> str:
    return "expected t, q1..q5, tau1..tau5 and optionally qd1..qd5, qdd1..qdd5"


#: Largest measurement file read, bytes (2 GiB: ~10 million rows of 11 columns). Checked
#: before reading, so that /dev/zero or a mistaken binary cannot exhaust memory.
MAX_FILE_BYTES = 2 << 30


def _lines(path: Path) -> Iterator[tuple[int, str]]:
    if not path.exists():
        raise InputError(f"{path}: no such file or directory")
    if not path.is_file():
        raise InputError(f"{path}: not a regular file")
    size = path.stat().st_size
    if size > MAX_FILE_BYTES:
        raise InputError(f"{path}: {size} bytes is more than the {MAX_FILE_BYTES} bytes accepted")
    # utf-8-sig: spreadsheet programs often start a CSV with a byte-order mark.
    with path.open(newline="", encoding="utf-8-sig") as f:
        for lineno, line in enumerate(f, start=1):
            if line.strip() and not line.lstrip().startswith("#"):
                yield lineno, line


def read_measurements(path: str | os.PathLike[str]) -> dict[str, np.ndarray]:
    """Reads a measurement CSV file (see :func:`_read`)."""
    try:
        return _read(Path(path))
    except UnicodeDecodeError:
        raise InputError(f"{path}: not a UTF-8 text (CSV) file") from None
    except csv.Error as e:
        raise InputError(f"{path}: not a readable CSV file ({e})") from None


def _read(path: Path) -> dict[str, np.ndarray]:
    """Reads a measurement CSV file.

    Returns a dict with ``t`` (N,), ``q`` and ``tau`` (N, 5) and, when present in the file,
    ``qd`` and ``qdd`` (N, 5). Raises InputError (one-line message naming the file, row and
    column) for a missing/misspelt column, a non-numeric or non-finite cell, non-increasing
    time or too few samples; OSError for an unreadable file.
    """
    rows = _lines(path)
    try:
        header_lineno, header_line = next(rows)
    except StopIteration:
        raise InputError(f"{path}: the file is empty; {_expected()}") from None
    header = [h.strip().lower() for h in next(csv.reader([header_line]))]
    seen: set[str] = set()
    for name in header:
        if name in seen:
            raise InputError(f"{path}: column '{name}' appears twice in the header")
        seen.add(name)
    missing = [c for c in REQUIRED_COLUMNS if c not in seen]
    for name in header:
        if name not in ALL_COLUMNS:
            # A close name among all columns; else the closest of those still missing (so
            # that 'time' is matched with 't').
            close = difflib.get_close_matches(name, ALL_COLUMNS, n=1) or (
                difflib.get_close_matches(name, missing, n=1, cutoff=0.3)
            )
            hint = f" (did you mean '{close[0]}'?)" if close else ""
            raise InputError(f"{path}: unknown column '{name}'{hint}; {_expected()}")
    if missing:
        names = ", ".join(f"'{c}'" for c in missing)
        plural = "s" if len(missing) > 1 else ""
        raise InputError(f"{path}: missing column{plural} {names}; {_expected()}")
    has_qd = any(c in seen for c in VELOCITY_COLUMNS)
    has_qdd = any(c in seen for c in ACCELERATION_COLUMNS)
    if has_qd != has_qdd:
        given, absent = ("qd", "qdd") if has_qd else ("qdd", "qd")
        raise InputError(
            f"{path}: {given}1..{given}5 given without {absent}1..{absent}5; give both (used "
            "as they are) or neither (derived from q by the preprocessing)"
        )
    for group, present in ((VELOCITY_COLUMNS, has_qd), (ACCELERATION_COLUMNS, has_qdd)):
        for name in group:
            if present and name not in seen:
                raise InputError(
                    f"{path}: missing column '{name}' (give all of {group[0]}..{group[-1]} or none)"
                )

    values: list[list[float]] = []
    for lineno, line in rows:
        cells = next(csv.reader([line]))
        if len(cells) != len(header):
            raise InputError(
                f"{path}: line {lineno} has {len(cells)} cells, the header "
                f"(line {header_lineno}) has {len(header)}"
            )
        row: list[float] = []
        for name, cell in zip(header, cells, strict=True):
            try:
                x = float(cell)
            except ValueError:
                raise InputError(
                    f"{path}: line {lineno}, column '{name}': '{cell.strip()}' is not a number"
                ) from None
            if not math.isfinite(x):
                raise InputError(
                    f"{path}: line {lineno}, column '{name}': {cell.strip()} is not finite"
                )
            row.append(x)
        values.append(row)

    n = len(values)
    if n < MIN_SAMPLES:
        raise InputError(f"{path}: too few samples ({n}); at least {MIN_SAMPLES} are needed")
    table = np.asarray(values, dtype=np.float64)
    col = {name: table[:, j] for j, name in enumerate(header)}
    t = col["t"]
    steps = np.diff(t)
    bad = np.flatnonzero(~(steps > 0))
    if bad.size:
        k = int(bad[0]) + 1
        raise InputError(
            f"{path}: time is not strictly increasing at data row {k + 1} "
            f"(t = {t[k]:g} s after {t[k - 1]:g} s)"
        )
    out = {
        "t": t.copy(),
        "q": np.column_stack([col[c] for c in POSITION_COLUMNS]),
        "tau": np.column_stack([col[c] for c in TORQUE_COLUMNS]),
    }
    if has_qd and has_qdd:
        out["qd"] = np.column_stack([col[c] for c in VELOCITY_COLUMNS])
        out["qdd"] = np.column_stack([col[c] for c in ACCELERATION_COLUMNS])
    return out


def format_measurements(
    t: np.ndarray,
    q: np.ndarray,
    tau: np.ndarray,
    qd: np.ndarray | None = None,
    qdd: np.ndarray | None = None,
) -> str:
    """The CSV text of a measurement file (see the module docstring), full float precision."""
    columns = ["t", *POSITION_COLUMNS, *TORQUE_COLUMNS]
    blocks = [np.asarray(t, dtype=np.float64)[:, None], np.asarray(q), np.asarray(tau)]
    if qd is not None and qdd is not None:
        columns += [*VELOCITY_COLUMNS, *ACCELERATION_COLUMNS]
        blocks += [np.asarray(qd), np.asarray(qdd)]
    table = np.hstack(blocks)
    lines = [",".join(columns)]
    lines.extend(",".join(repr(float(x)) for x in row) for row in table)
    return "\n".join(lines) + "\n"


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike[str]) -> Iterator[Path]:
    """Yields a temporary path next to ``path``; on success it replaces ``path`` at once.

    On an exception the temporary file is removed and an existing ``path`` is left as it was.
    """
    path = Path(path)
    parent = path.parent if str(path.parent) else Path(".")
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=parent)
    os.close(fd)
    try:
        yield Path(tmp)
        # mkstemp makes the file private (0600); give it the permissions of a normal file.
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


def write_text_atomic(path: str | os.PathLike[str], text: str) -> None:
    """Writes ``text`` to ``path`` through :func:`atomic_path`."""
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")


def write_atomic(path: str | os.PathLike[str], write: Callable[[Path], None]) -> None:
    """Calls ``write(tmp_path)`` and moves the result to ``path`` only if it succeeds."""
    with atomic_path(path) as tmp:
        write(tmp)
