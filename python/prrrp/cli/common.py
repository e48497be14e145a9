"""What every command of the ``prrrp`` command line shares: exit codes, one-line errors,
progress bars, JSON output, argument types."""

from __future__ import annotations

import argparse
import json
import math
import shutil
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any, NoReturn

import numpy as np

from prrrp import bags, signals
from prrrp._prrrp import MAX_FACTOR, MIN_FACTOR

EXIT_OK = 0
EXIT_FAILED = 1
EXIT_USAGE = 2
EXIT_INTERRUPTED = 130

#: The robot of a command without --robot: the built-in arm of Urrea & Pascal 2017.
DEFAULT_ROBOT = "paper"


class CliError(Exception):
    """A user-facing failure: the message is printed as one line."""

    def __init__(self, message: str, code: int = EXIT_USAGE) -> None:
        super().__init__(message)
        self.code = code


# ---------------------------------------------------------------------------------- progress


class Progress:
    """Progress bars (tqdm) on stderr when it is a terminal; silent otherwise.

    Call as ``progress(stage, done, total)``; a new stage closes the previous bar.
    """

    def __init__(self, enabled: bool | None = None) -> None:
        self.enabled = sys.stderr.isatty() if enabled is None else enabled
        self._bar: Any = None
        self._stage: str | None = None

    def __call__(self, stage: str, done: int, total: int) -> None:
        # Raising here stops the running computation (see prrrp.signals).
        signals.checkpoint()
        if not self.enabled:
            return
        from tqdm import tqdm

        if stage != self._stage or self._bar is None:
            self.close()
            self._stage = stage
            size = shutil.get_terminal_size()
            self._bar = tqdm(
                total=max(int(total), 1),
                desc=f"{stage:<13}",
                file=sys.stderr,
                leave=False,
                # tqdm draws nothing on a terminal that reports a size of 0 × 0 (some
                # pseudo-terminals do): fall back to 80 × 24 then.
                ncols=size.columns or 80,
                nrows=size.lines or 24,
            )
        if total and self._bar.total != total:
            self._bar.total = int(total)
        self._bar.n = int(done)
        self._bar.refresh()

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()
            self._bar = None
            self._stage = None


# ---------------------------------------------------------------------------------- helpers


def attr(obj: Any, name: str, default: Any = None) -> Any:
    """Field ``name`` of a result that may be a dict or an object."""
    if isinstance(obj, dict):
        return obj.get(name, default)
    return getattr(obj, name, default)


def as_list(x: Any) -> Any:
    if x is None:
        return None
    if isinstance(x, np.ndarray):
        return x.tolist()
    if isinstance(x, np.generic):
        return x.item()
    return x


def json_default(x: Any) -> Any:
    if isinstance(x, np.ndarray | np.generic):
        return x.tolist()
    raise TypeError(f"not JSON serialisable: {type(x).__name__}")


def dump_json(data: Any, path: Path) -> None:
    with path.open("w", encoding="utf-8") as f:
        json.dump(data, f, indent=1, default=json_default, allow_nan=True)
        f.write("\n")


def check_output_file(path: Path) -> None:
    if path.is_dir():
        raise CliError(f"output {path} is a directory; give a file name")
    if path.exists() and not path.is_file():
        # Replaced by a regular file before: /dev/null run as root would be gone.
        raise CliError(f"output {path} is a device, pipe or socket; give a file name")
    parent = path.parent if str(path.parent) else Path(".")
    if not parent.is_dir():
        raise CliError(f"output directory {parent} does not exist")


def print_table(header: Sequence[str], rows: Sequence[Sequence[str]]) -> None:
    widths = [max(len(h), *(len(r[k]) for r in rows)) for k, h in enumerate(header)]
    print("  ".join(h.rjust(w) for h, w in zip(header, widths, strict=True)))
    for r in rows:
        print("  ".join(c.rjust(w) for c, w in zip(r, widths, strict=True)))


def seed(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not an integer: {text!r}") from None
    if not 0 <= value < 2**64:
        raise argparse.ArgumentTypeError(f"must be between 0 and 2^64 - 1, got {value}")
    return value


def number(text: str) -> float:
    """An option's finite number (argparse's ``float`` takes nan and inf, which reached
    the library as "must be a JSON-serialisable dict")."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"must be a finite number, got {text!r}")
    return value


class Parser(argparse.ArgumentParser):
    """Usage errors in one line on stderr (argparse prints the whole usage first)."""

    def error(self, message: str) -> NoReturn:
        error(f"{message} (see `{self.prog} --help`)")
        raise SystemExit(EXIT_USAGE)


def nonempty_path(text: str) -> str:
    if not text.strip():
        raise argparse.ArgumentTypeError("an empty path")
    return text


def check_factor(flag: str, v: float | None, low: float = MIN_FACTOR, unit: str = "") -> None:
    """Refuses a factor outside [low, MAX_FACTOR] (in ``unit``), naming its flag (None:
    not given).

    Widths and noise factors are squared into covariances: 1e300 made them infinite and
    1e-300 zero (a payload mass of 1e-300 kg gave 217 kg·m² of inertia). The library
    refuses them too, but by its field's name, not the flag's.
    """
    # NaN fails both comparisons; `is_factor` is this range with low = MIN_FACTOR.
    if v is not None and not low <= v <= MAX_FACTOR:
        raise CliError(f"{flag} must be between {low:g} and {MAX_FACTOR:g}{unit}, got {v:g}")


def first_line(e: BaseException) -> str:
    text = str(e).strip() or type(e).__name__
    return text.splitlines()[0]


def describe(e: BaseException) -> str:
    """An error as one line a command-line user reads: a robot file's error as
    ``FILE: [ELEMENT: ]MESSAGE``, the library's `code` quotes as plain 'quotes'."""
    file, element, message = (getattr(e, k, None) for k in ("file", "element", "message"))
    if isinstance(file, str) and isinstance(message, str):
        where = f"{file}: " + (f"{element}: " if element and element != "file" else "")
        return where + message.strip().splitlines()[0]
    return first_line(e).replace("`", "'")


def options(values: Sequence[str]) -> str:
    """``a, b or c``: a list of choices as a message says it (not a Python tuple)."""
    values = list(values)
    return values[0] if len(values) == 1 else ", ".join(values[:-1]) + " or " + values[-1]


def add_command(
    sub: Any, name: str, run: Any, *, help: str, description: str, epilog: str | None = None
) -> Parser:
    """The parser of the command ``prrrp NAME``, which ``run(args) -> int`` carries out."""
    p = sub.add_parser(name, help=help, description=description, epilog=epilog)
    p.set_defaults(func=run)
    return p


def add_out_argument(
    p: Any, metavar: str = "DIR", help: str = "output folder", default: str | None = None
) -> None:
    """``--out``: required unless it has a ``default`` (which ``help`` then names)."""
    p.add_argument(
        "--out",
        required=default is None,
        default=default,
        type=nonempty_path,
        metavar=metavar,
        help=help,
    )


def add_topic_argument(p: Any) -> None:
    """``--topic``: the JointState topic of a ROS 2 bag."""
    p.add_argument(
        "--topic",
        default=bags.DEFAULT_TOPIC,
        help=f"JointState topic of a bag (default: {bags.DEFAULT_TOPIC})",
    )


def add_robot_arguments(p: Any, default: str = DEFAULT_ROBOT) -> None:
    """``--robot`` (``default`` says what a command without it loads: the paper's arm) and
    the ``--base``/``--tip`` links of a URDF, as every command that loads a robot takes them."""
    p.add_argument(
        "--robot",
        metavar="ROBOT",
        help=f'robot file (.urdf or .toml), or "{DEFAULT_ROBOT}": the 5-joint arm of Urrea & '
        f"Pascal 2017 (default: {default})",
    )
    p.add_argument(
        "--base", metavar="LINK", help="URDF: first link of the chain (default: the root link)"
    )
    p.add_argument(
        "--tip",
        metavar="LINK",
        help="URDF: last link of the chain (default: the end of the movable joints)",
    )


def add_drive_gains_argument(p: Any, default: str) -> None:
    """``--drive-gains``: the log holds motor currents, converted to joint torques."""
    p.add_argument(
        "--drive-gains",
        metavar="K1,...,KN|FILE.json",
        help="the log has motor currents i1..iN (A): joint-side drive gains, N·m/A per actuator "
        "(torque constant × gear ratio), or a JSON file with them (a model.json of `prrrp "
        f"identify --payload-run`); torques are Cᵀ·(K∘i); a list that starts with a "
        f"negative gain needs the = form, --drive-gains=-9,9,… (default: {default})",
    )


def add_motor_side_argument(p: Any, default: str) -> None:
    """``--motor-side``: the log's positions and torques are the motors'."""
    p.add_argument(
        "--motor-side",
        action="store_true",
        help="the log's positions and torques are motor-side: mapped to the joints through the "
        f"gear_ratios and coupling of the robot file's [actuators] (default: {default})",
    )


def check_chain_options(args: argparse.Namespace) -> None:
    """``--base``/``--tip`` pick the chain of a URDF: without a ``--robot`` URDF they are
    a usage error, not silently ignored."""
    given = [f"--{k}" for k in ("base", "tip") if getattr(args, k, None) is not None]
    if not given:
        return
    robot = getattr(args, "robot", None)
    if not robot:
        verb = "need" if len(given) > 1 else "needs"
        raise CliError(f"{' and '.join(given)} {verb} --robot ROBOT.urdf (they pick its chain)")
    if not str(robot).lower().endswith(".urdf"):
        raise CliError(
            f"{' and '.join(given)} {'apply' if len(given) > 1 else 'applies'} to a URDF robot "
            f"file; {robot} is not one (a TOML "
            "file describes its chain itself)"
        )


def error(message: str) -> None:
    print(f"prrrp: error: {message}", file=sys.stderr)


def coulomb_scale(text: str | None) -> str | float | None:
    """``--coulomb-scale auto|V``: ``"auto"``, a speed scale ≥ 0 (rad/s), or None (not
    given)."""
    if text is None or text == "auto":
        return text
    try:
        v = float(text)
    except ValueError:
        raise CliError(f"--coulomb-scale must be auto or a number (rad/s), got {text!r}") from None
    if not (v == 0 or MIN_FACTOR <= v <= MAX_FACTOR):
        raise CliError(
            f"--coulomb-scale must be auto, 0 (exact sign) or between {MIN_FACTOR:g} and "
            f"{MAX_FACTOR:g} rad/s, got {text}"
        )
    return v


def friction_terms(text: str) -> str | None:
    """``--friction viscous,coulomb,offset`` (or ``none``) as the bindings' "a+b" form.
    The Python API's spelling ``viscous+coulomb+offset`` is accepted too."""
    terms = [t.strip() for t in text.replace("+", ",").split(",")]
    if terms == ["none"]:
        return None
    bad = [t for t in terms if t not in ("viscous", "coulomb", "offset")]
    if bad:
        what = f"unknown term '{bad[0]}'" if bad[0] else "an empty term"
        raise CliError(
            f"--friction: {what} in {text!r} (comma-separated from viscous, coulomb, offset, "
            "or none)"
        )
    twice = sorted({t for t in terms if terms.count(t) > 1})
    if twice:
        raise CliError(f"--friction: '{twice[0]}' is given twice in {text!r}")
    return "+".join(terms)


#: A joint is at its noise floor when its torque error is within this factor of the
#: measured torque's noise and is at least NOISE_FLOOR_PERCENT % of its RMS torque.
NOISE_FLOOR_FACTOR = 1.25
NOISE_FLOOR_PERCENT = 25.0


def say_noise_floor(
    joints: Sequence[str],
    types: str,
    noise: np.ndarray,
    error_rms: np.ndarray,
    percent: np.ndarray,
) -> None:
    """Prints the joints whose large error % is the log's torque noise, not the model's:
    ``error_rms`` (N·m or N) within :data:`NOISE_FLOOR_FACTOR` of ``noise`` (the measured
    torque's, N·m or N) and ``percent`` at least :data:`NOISE_FLOOR_PERCENT`. Nothing when
    no joint is; NaN entries (no torque, too few rows) never are."""
    with np.errstate(invalid="ignore"):
        floor = (error_rms <= NOISE_FLOOR_FACTOR * noise) & (percent >= NOISE_FLOOR_PERCENT)
    if not floor.any():
        return
    named = ", ".join(
        f"{j} (noise {noise[i]:.2g} {'N' if types[i] == 'P' else 'N·m'})"
        for i, j in enumerate(joints)
        if floor[i]
    )
    print(
        f"at the noise floor: {named}: the error is the torque's own noise (estimated from "
        "its third differences) and the torque hardly rises above it in this log, so the "
        "error % says little about the model there; excite these joints harder to check them"
    )
