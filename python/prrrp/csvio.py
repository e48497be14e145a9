"""Measurement files of the ``prrrp`` command line, and safe writing of output files.

CSV format (comma-separated, one header line, then one row per sample), for a robot of N
joints (N = 5 for the paper's arm, :func:`read_measurements`; any N, :func:`read_table`):

- ``t``: time, s, increasing (uniform sampling for the paper's preprocessing, e.g. 0.02 s; a
  real log read by :func:`read_table` may repeat time stamps, which ``prrrp.preprocess_log``
  drops);
- ``q1..qN``: joint positions, m (prismatic) or rad (revolute) — for the paper's arm
  [d1, θ2, θ3, θ4, d5];
- ``tau1..tauN``: generalised forces, N or N·m — for the paper's arm [F1, τ2, τ3, τ4, F5];
  a log of any robot (:func:`read_table` with ``real_log``) may give motor currents
  ``i1..iN`` (A) instead, converted with drive gains (``prrrp.drives``);
- optional ``qd1..qdN`` (m/s, rad/s) and ``qdd1..qddN`` (m/s², rad/s²): when both are given
  they are used as they are; otherwise velocities and accelerations are obtained by the
  preprocessing (zero-phase low-pass filter and differentiation). A real log may give
  ``qd`` alone (measured velocities, used by ``prrrp.preprocess_log``).

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
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from prrrp import signals
from prrrp._prrrp import MAX_MAGNITUDE, InvalidInputError

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


class InputError(InvalidInputError):
    """Bad input file: the message is one line saying what is wrong and where."""


def _expected(n: int | None = NDOF) -> str:
    k = "N" if n is None else str(n)
    return (
        f"expected t, q1..q{k}, tau1..tau{k} (or motor currents i1..i{k}) and optionally "
        f"qd1..qd{k}, qdd1..qdd{k}"
    )


def columns(n: int) -> dict[str, tuple[str, ...]]:
    """The column names of a measurement file of ``n`` joints, by group."""
    return {
        "q": tuple(f"q{i}" for i in range(1, n + 1)),
        "tau": tuple(f"tau{i}" for i in range(1, n + 1)),
        "qd": tuple(f"qd{i}" for i in range(1, n + 1)),
        "qdd": tuple(f"qdd{i}" for i in range(1, n + 1)),
        "i": tuple(f"i{i}" for i in range(1, n + 1)),
    }


#: Most joints a measurement file may have (a bound against a mistaken or hostile header).
MAX_JOINTS = 1000


#: Largest measurement file read, bytes (2 GiB: ~10 million rows of 11 columns). Checked
#: before reading, so that /dev/zero or a mistaken binary cannot exhaust memory.
MAX_FILE_BYTES = 2 << 30


def _check_file(path: Path) -> int:
    """The size of the regular file ``path``, bytes; InputError when there is none or it
    is larger than :data:`MAX_FILE_BYTES`."""
    if not path.exists():
        raise InputError(f"{path}: no such file or directory")
    if not path.is_file():
        raise InputError(f"{path}: not a regular file")
    size = path.stat().st_size
    if size > MAX_FILE_BYTES:
        raise InputError(f"{path}: {size} bytes is more than the {MAX_FILE_BYTES} bytes accepted")
    return size


#: Block of the file the native parser reads at a time, bytes: the text is never held
#: whole, so the memory is the numbers' (a whole 60 000-row file read at once peaked at
#: 3.4× the numbers; test_input_bounds).
FAST_BLOCK_BYTES = 1 << 20


def _fast_table(path: Path) -> tuple[int, str, np.ndarray] | None:
    """(header line number, header line, numbers (rows × cells)) of a plain file, parsed
    natively block by block (``prrrp._prrrp.read_numeric_csv``, ~10× faster; each block
    after the first is parsed behind the header line), or None: a file with anything else
    (quoted cells, a bad cell, a row of another width, ...) is read by :func:`_numbers`,
    whose messages say what is wrong and where."""
    from prrrp._prrrp import read_numeric_csv

    first: tuple[int, str, int] | None = None
    head = b""
    parts: list[np.ndarray] = []
    carry = b""
    with path.open("rb") as f:
        while True:
            chunk = f.read(FAST_BLOCK_BYTES)
            data = carry + chunk
            if chunk:
                cut = data.rfind(b"\n") + 1
                if cut == 0:  # a line longer than a block: read on
                    carry = data
                    continue
                body, carry = data[:cut], data[cut:]
            else:
                body, carry = data, b""
                if not body:
                    break
            found = read_numeric_csv(head + body)
            if found is None:
                return None
            header, lineno, rows, width, values = found
            if first is None:
                first = (lineno, header, width)
                head = (header + "\n").encode()
            elif header != first[1] or width != first[2]:
                return None
            if rows:
                parts.append(np.frombuffer(values, dtype=np.float64).reshape(rows, width))
            if not chunk:
                break
    if first is None:
        return None
    lineno, header, width = first
    table = np.concatenate(parts) if parts else np.empty((0, width))
    return lineno, header, table


def _lines(path: Path) -> Iterator[tuple[int, str]]:
    _check_file(path)
    # utf-8-sig: spreadsheet programs often start a CSV with a byte-order mark.
    with path.open(newline="", encoding="utf-8-sig") as f:
        for lineno, line in enumerate(f, start=1):
            if line.strip() and not line.lstrip().startswith("#"):
                yield lineno, line


def read_measurements(path: str | os.PathLike[str]) -> dict[str, np.ndarray]:
    """Reads a measurement CSV file of the paper's arm (5 joints, strictly increasing time,
    ``qd`` and ``qdd`` both or neither); see :func:`read_table`."""
    return read_table(path, NDOF)


def read_table(
    path: str | os.PathLike[str],
    dof: int | None = None,
    *,
    real_log: bool = False,
    need_tau: bool = True,
) -> dict[str, np.ndarray]:
    """Reads a measurement CSV file of ``dof`` joints (None: as many as the header has).

    Returns a dict with ``t`` (S,), ``q`` and ``tau`` (S, N) and, when present in the file,
    ``qd`` and ``qdd`` (S, N). With ``real_log`` a file may give motor currents ``i1..iN``
    (A) instead of torques: the result then has ``current`` (S, N) and no ``tau``. With
    ``real_log`` the file is a raw log for
    ``prrrp.preprocess_log``: time stamps may repeat (it drops the repeats), and measured
    velocities ``qd`` may come without ``qdd``. Raises InputError (one-line message naming the
    file, row and column) for a missing/misspelt column, a non-numeric or non-finite cell,
    time that is not increasing (or, with ``real_log``, that runs backwards) or too few
    samples; OSError for an unreadable file. Without ``need_tau`` the torque columns may be
    absent (all of them; the result then has no ``tau``).
    """
    try:
        return _read(Path(path), dof, real_log, need_tau)
    except UnicodeDecodeError:
        raise InputError(f"{path}: not a UTF-8 text (CSV) file") from None
    except csv.Error as e:
        raise InputError(f"{path}: not a readable CSV file ({e})") from None


def _dof_of(path: Path, header: list[str]) -> int:
    """The joint count a header names: the largest k of its q<k> columns."""
    ks = [int(h[1:]) for h in header if h.startswith("q") and h[1:].isdigit()]
    if not ks:
        raise InputError(f"{path}: no joint position columns q1, q2, ...; {_expected(None)}")
    n = max(ks)
    if n > MAX_JOINTS:
        raise InputError(f"{path}: column 'q{n}' asks for {n} joints, more than {MAX_JOINTS}")
    return n


def _read(path: Path, dof: int | None, real_log: bool, need_tau: bool) -> dict[str, np.ndarray]:
    _check_file(path)
    fast = _fast_table(path)
    rows = _lines(path)
    if fast is not None:
        header_lineno, header_line, _ = fast
    else:
        try:
            header_lineno, header_line = next(rows)
        except StopIteration:
            raise InputError(f"{path}: the file is empty; {_expected(dof)}") from None
    header = [h.strip().lower() for h in next(csv.reader([header_line]))]
    seen: set[str] = set()
    for name in header:
        if name in seen:
            raise InputError(f"{path}: column '{name}' appears twice in the header")
        seen.add(name)
    n = _dof_of(path, header) if dof is None else dof
    groups = columns(n)
    required = ("t", *groups["q"], *groups["tau"])
    every = (*required, *groups["qd"], *groups["qdd"], *(groups["i"] if real_log else ()))
    has_current = real_log and any(c in seen for c in groups["i"])
    has_tau = (need_tau and not has_current) or any(c in seen for c in groups["tau"])
    if has_current and has_tau:
        raise InputError(
            f"{path}: both joint torques tau1..tau{n} and motor currents i1..i{n}; give one"
        )
    if not has_tau:
        required = ("t", *groups["q"], *(groups["i"] if has_current else ()))
    missing = [c for c in required if c not in seen]
    for name in header:
        if name not in every:
            # A close name among all columns; else the closest of those still missing (so
            # that 'time' is matched with 't').
            close = difflib.get_close_matches(name, every, n=1) or (
                difflib.get_close_matches(name, missing, n=1, cutoff=0.3)
            )
            hint = f" (did you mean '{close[0]}'?)" if close else ""
            if not close and dof is not None and name[:1] in ("q", "t") and name[-1:].isdigit():
                hint = f" (the robot has {n} joints)"
            raise InputError(f"{path}: unknown column '{name}'{hint}; {_expected(n)}")
    if missing:
        names = ", ".join(f"'{c}'" for c in missing)
        plural = "s" if len(missing) > 1 else ""
        raise InputError(f"{path}: missing column{plural} {names}; {_expected(n)}")
    has_qd = any(c in seen for c in groups["qd"])
    has_qdd = any(c in seen for c in groups["qdd"])
    if (has_qdd and not has_qd) or (has_qd and not has_qdd and not real_log):
        given, absent = ("qd", "qdd") if has_qd else ("qdd", "qd")
        raise InputError(
            f"{path}: {given}1..{given}{n} given without {absent}1..{absent}{n}; give both (used "
            "as they are) or neither (derived from q by the preprocessing)"
        )
    for group, present in ((groups["qd"], has_qd), (groups["qdd"], has_qdd)):
        for name in group:
            if present and name not in seen:
                raise InputError(
                    f"{path}: missing column '{name}' (give all of {group[0]}..{group[-1]} or none)"
                )

    table = fast[2] if fast is not None else _numbers(path, rows, header, header_lineno)
    n = len(table)
    if n < MIN_SAMPLES:
        raise InputError(f"{path}: too few samples ({n}); at least {MIN_SAMPLES} are needed")
    big = np.argwhere(np.abs(table) >= MAX_MAGNITUDE)
    if big.size:
        i, j = big[0]
        raise InputError(
            f"{path}: data row {i + 1}, column '{header[j]}': {table[i, j]:g} {TOO_LARGE}"
        )
    col = {name: table[:, j] for j, name in enumerate(header)}
    t = col["t"]
    steps = np.diff(t)
    bad = np.flatnonzero(~(steps >= 0) if real_log else ~(steps > 0))
    if bad.size:
        k = int(bad[0]) + 1
        what = "runs backwards" if real_log else "is not strictly increasing"
        raise InputError(
            f"{path}: time {what} at data row {k + 1} (t = {t[k]:g} s after {t[k - 1]:g} s)"
        )
    out = {"t": t.copy()}
    for key, present in (
        ("q", True),
        ("tau", has_tau),
        ("qd", has_qd),
        ("qdd", has_qdd),
        ("i", has_current),
    ):
        if present:
            out["current" if key == "i" else key] = np.column_stack([col[c] for c in groups[key]])
    return out


#: How a value of :data:`prrrp.MAX_MAGNITUDE` or more is refused.
TOO_LARGE = (
    "is 1e100 or more in magnitude: no joint turns, moves or pushes that far "
    "(rad, m, N·m, N); check the log's units"
)

#: Lines parsed per block by :func:`_numbers`: large enough that numpy does the work,
#: small enough that the block's Python strings (≈ 60 bytes per cell) stay about 2 MB.
CHUNK_LINES = 2048


def _numbers(
    path: Path, rows: Iterator[tuple[int, str]], header: list[str], header_lineno: int
) -> np.ndarray:
    """The data lines as one float64 array (rows × columns), parsed block by block into a
    growing array: memory is the numbers' 8 bytes each (the array is sized from the file
    size and the first block's line length, and grows by half when short) plus one block
    of text, not Python lists of floats (≈ 28× the file's size)."""
    width = len(header)
    size = path.stat().st_size
    table = np.empty((0, width))
    count = 0
    chunk: list[str] = []
    linenos: list[int] = []

    def flush() -> None:
        nonlocal table, count
        if any('"' in line for line in chunk):  # quoted cells: the csv module, line by line
            cells = [next(csv.reader([line])) for line in chunk]
        else:
            cells = [line.rstrip("\r\n").split(",") for line in chunk]
        for lineno, row in zip(linenos, cells, strict=True):
            if len(row) != width:
                raise InputError(
                    f"{path}: line {lineno} has {len(row)} cells, the header "
                    f"(line {header_lineno}) has {width}"
                )
        try:
            block = np.array(cells, dtype=np.float64).reshape(len(cells), width)
        except ValueError:
            block = None
        if block is None or not np.isfinite(block).all():
            block = _parse_slowly(path, header, linenos, cells)
        if count + len(block) > len(table):
            if count == 0:
                # Rows in the file, from the length of the lines seen so far (+5 %).
                line_bytes = max(sum(len(x) for x in chunk) / len(chunk), 1.0)
                guess = int(1.05 * size / line_bytes) + 1
            else:
                guess = len(table) + len(table) // 2
            grown = np.empty((max(guess, count + len(block)), width))
            grown[:count] = table[:count]
            table = grown
        table[count : count + len(block)] = block
        count += len(block)
        chunk.clear()
        linenos.clear()

    for lineno, line in rows:
        chunk.append(line)
        linenos.append(lineno)
        if len(chunk) == CHUNK_LINES:
            flush()
    if chunk:
        flush()
    return table[:count]


def _parse_slowly(
    path: Path, header: list[str], linenos: list[int], cells: list[list[str]]
) -> np.ndarray:
    """A block cell by cell with Python's float(): the InputError of its first cell that
    is not a finite number (line and column named), or the block."""
    out = np.empty((len(cells), len(header)))
    for i, (lineno, row) in enumerate(zip(linenos, cells, strict=True)):
        for j, (name, cell) in enumerate(zip(header, row, strict=True)):
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
            out[i, j] = x
    return out


def format_measurements(
    t: np.ndarray,
    q: np.ndarray,
    tau: np.ndarray,
    qd: np.ndarray | None = None,
    qdd: np.ndarray | None = None,
) -> str:
    """The CSV text of a measurement file of N = q.shape[1] joints (see the module
    docstring), full float precision."""
    q = np.atleast_2d(np.asarray(q, dtype=np.float64))
    groups = columns(q.shape[1])
    names = ["t", *groups["q"], *groups["tau"]]
    blocks = [np.asarray(t, dtype=np.float64)[:, None], q, np.asarray(tau)]
    if qd is not None and qdd is not None:
        names += [*groups["qd"], *groups["qdd"]]
        blocks += [np.asarray(qd), np.asarray(qdd)]
    return format_table(names, np.hstack(blocks))


def format_table(names: list[str], table: np.ndarray) -> str:
    """CSV text of a header ``names`` and the rows of ``table``, full float precision."""
    lines = [",".join(names)]
    lines.extend(",".join(repr(float(x)) for x in row) for row in table)
    return "\n".join(lines) + "\n"


#: Rows formatted at a time by :func:`write_table`.
WRITE_CHUNK_ROWS = 10_000


def write_table(
    f: Any, names: Sequence[str], table: np.ndarray, integer_columns: Sequence[str] = ()
) -> None:
    """Writes the CSV of :func:`format_table` to the text file ``f`` block by block
    (memory: one block of text, not the whole file's); ``integer_columns`` are written
    as integers."""
    table = np.asarray(table, dtype=np.float64)
    ints = [k for k, name in enumerate(names) if name in integer_columns]
    f.write(",".join(names) + "\n")
    for start in range(0, len(table), WRITE_CHUNK_ROWS):
        block = table[start : start + WRITE_CHUNK_ROWS].tolist()
        for row in block:
            for k in ints:
                row[k] = int(row[k])
        f.write("".join(",".join(map(repr, row)) + "\n" for row in block))


def write_table_atomic(
    path: str | os.PathLike[str],
    names: Sequence[str],
    table: np.ndarray,
    integer_columns: Sequence[str] = (),
) -> None:
    """:func:`write_table` into ``path`` through :func:`atomic_path`."""
    with atomic_path(path) as tmp, tmp.open("w", encoding="utf-8") as f:
        write_table(f, names, table, integer_columns)


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike[str]) -> Iterator[Path]:
    """Yields a temporary path next to ``path``; on success it replaces ``path`` at once.

    On an exception the temporary file is removed and an existing ``path`` is left as it was.
    A symbolic link is followed: its target is replaced and the link kept.
    """
    path = Path(path)
    if path.is_symlink():
        path = Path(os.path.realpath(path))
    if path.exists() and not path.is_file():
        # os.replace would swap a device node or a FIFO for a regular file.
        raise InputError(f"{path}: a directory, device, pipe or socket; give a file name")
    parent = path.parent if str(path.parent) else Path(".")
    if not parent.is_dir():
        raise InputError(f"{path}: the folder {parent} does not exist; create it first")
    tmp = None
    try:
        with signals.deferred():  # a Ctrl-C inside mkstemp would leave a file we cannot name
            fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=parent)
            os.close(fd)
        yield Path(tmp)
        # mkstemp makes the file private (0600); give it the permissions of a normal file.
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)
        signals.checkpoint()  # a Ctrl-C Python dropped must not let the file land
        os.replace(tmp, path)
    except BaseException:
        if tmp is not None:
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
