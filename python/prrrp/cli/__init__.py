"""The ``prrrp`` command line (also ``python -m prrrp``).

Subcommands (ROBOT is a ``.urdf`` with ``--base``/``--tip`` links, a ``.toml`` robot file, or
``paper``, the arm of Urrea & Pascal 2017, which is the default):

- ``prrrp reproduce [--out DIR] [--seed N]``: the paper's whole study (excitation, simulation,
  the four estimators, validation, sensitivity) → ``DIR/results.json``, ``DIR/report.md`` and
  the figures ``DIR/*.png``.
- ``prrrp excite [--robot ROBOT] --duration S --out DIR``: an exciting trajectory within the
  robot's limits → ``DIR/trajectory.csv`` (:mod:`prrrp.cli.excite`);
- ``prrrp simulate [--robot ROBOT] [--trajectory TRAJ.csv] --out DIR``: the robot tracking it
  (or a trajectory designed first) → ``DIR/data.csv`` (:mod:`prrrp.cli.simulate`);
- ``prrrp identify DATA [--robot ROBOT] --out DIR``: model.json, report.md and figures from a
  CSV or a ROS 2 bag (:mod:`prrrp.cli.identify`);
- ``prrrp predict MODEL.json DATA --out tau.csv``: a saved model's torques for recorded states.
- ``prrrp payload LOADED --model ARM.json [--mass KG] --out DIR``: the payload an identified arm
  carries (:mod:`prrrp.cli.payload`); ``prrrp identify UNLOADED --robot R --payload-run LOADED
  --payload-mass KG --out DIR``: drive gains from current logs and a payload of known mass.
- ``prrrp track DATA [--robot ROBOT] [--model PRIOR.json] [--payload] --out DIR``: the log fed
  one row at a time to the online identifier (:mod:`prrrp.cli.track`).

- ``prrrp benchmark [--robot ROBOT] --methods ls,rls --noise 1,3 --rates 50,100 --seeds N
  [--workers K | --dask ADDRESS] --out DIR``: a Monte-Carlo benchmark of the estimators
  (:mod:`prrrp.cli.benchmark`).

The previous release's spellings (``identify`` of the closed-form arm without ``--robot``, an
``--out`` naming a file) still work for one release: :mod:`prrrp.cli.deprecated`.

The measurement CSV format is documented in :mod:`prrrp.csvio`. Exit codes: 0 success,
1 a computation failed (e.g. an estimator diverged), 2 bad usage or bad input, 130
interrupted. Errors are one line on stderr, never a traceback.
"""

from __future__ import annotations

import argparse
import atexit
import contextlib
import os
import sys
from collections.abc import Sequence
from typing import NoReturn

import prrrp
from prrrp import signals
from prrrp.cli import benchmark, excite, identify, payload, predict, reproduce, simulate, track
from prrrp.cli.common import (
    EXIT_FAILED,
    EXIT_INTERRUPTED,
    EXIT_OK,
    EXIT_USAGE,
    CliError,
    Parser,
    check_chain_options,
    describe,
    error,
)
from prrrp.cli.simulate import DEFAULT_Q_NOISE, DEFAULT_TAU_NOISE

__all__ = [
    "DEFAULT_Q_NOISE",
    "DEFAULT_TAU_NOISE",
    "EXIT_FAILED",
    "EXIT_INTERRUPTED",
    "EXIT_OK",
    "EXIT_USAGE",
    "CliError",
    "build_parser",
    "console",
    "main",
]

#: One module per command, each with ``add_parser(subparsers)`` and ``run(args) -> int``.
COMMANDS = (reproduce, excite, simulate, identify, predict, payload, track, benchmark)


def build_parser() -> argparse.ArgumentParser:
    parser = Parser(
        prog="prrrp",
        description="Dynamic parameter identification of robot manipulators: any arm from its "
        "URDF or TOML file, or the built-in PRRRP arm of Urrea & Pascal 2017 (--robot paper, "
        "the default): excite, simulate, identify, predict; and the paper's study (reproduce).",
        epilog="Run `prrrp reproduce` for the paper's whole study; `prrrp COMMAND --help` "
        "for each command.",
    )
    parser.add_argument("--version", action="version", version=f"prrrp {prrrp.__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for command in COMMANDS:
        command.add_parser(sub)
    return parser


def _oserror_message(e: OSError) -> str:
    what = e.filename if e.filename is not None else ""
    reason = e.strerror or str(e)
    if isinstance(e, FileNotFoundError):
        return f"{what}: no such file or directory"
    return f"{what}: {reason}" if what else reason


def main(argv: Sequence[str] | None = None) -> int:
    """Runs the command line; returns the exit code (argparse exits itself on usage errors)."""
    args = build_parser().parse_args(argv)
    signals.install()
    try:
        try:
            check_chain_options(args)
            code = int(args.func(args))
        except Exception:
            # An error after a signal whose exception Python dropped is the signal's
            # aftermath (seen in CI: matplotlib, stopped halfway, then raised "Invalid
            # bounding box"): the run ends for the signal, 130 / 143, not with exit 2.
            signals.checkpoint()
            raise
        # A signal whose exception Python dropped (see prrrp.signals) still ends the run.
        signals.checkpoint()
        return code
    except CliError as e:
        error(str(e))
        return e.code
    except KeyboardInterrupt:
        error("interrupted")
        return EXIT_INTERRUPTED
    except OSError as e:
        error(_oserror_message(e))
        return EXIT_USAGE
    except prrrp.RankDeficientError as e:
        error(
            f"the data does not excite every parameter (rank deficient, cond(W) = "
            f"{getattr(e, 'cond', float('inf')):.3g}): {describe(e)}"
        )
        return EXIT_USAGE
    except (prrrp.InvalidInputError, ValueError) as e:
        error(describe(e))
        return EXIT_USAGE
    except prrrp.PrrrpError as e:
        error(describe(e))
        return EXIT_FAILED


def console() -> NoReturn:
    """The ``prrrp`` command (and ``python -m prrrp``): :func:`main`, then exit with its code.

    A run ended by Ctrl-C or SIGTERM exits as soon as its cleanup is done: the atexit
    handlers run, then the process ends without the interpreter's teardown, which waits for
    the daemon thread still importing matplotlib (``drawing.preload``) and then frees every
    module. Measured on `prrrp reproduce` stopped at 2.5 s beside two CPU hogs: 0.72–1.10 s
    from the signal to the exit with the teardown (0.27–0.38 s without the thread),
    0.06–0.09 s without it."""
    try:
        code = main()
    except SystemExit as e:
        if signals.received() is None:
            raise  # argparse's --help, --version and usage errors
        code = e.code if isinstance(e.code, int) else EXIT_INTERRUPTED
    except KeyboardInterrupt:
        # A second Ctrl-C during the first one's cleanup, in main's own handler (which
        # has said "interrupted", or was about to).
        code = EXIT_INTERRUPTED
    if signals.received() is None:
        sys.exit(code)
    # The run is ending for a signal: another one (a second Ctrl-C, or `timeout`'s to the
    # process group) would raise inside multiprocessing's exit handler and print its
    # traceback.
    signals.ignore()
    atexit._run_exitfuncs()
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(Exception):
            stream.flush()
    os._exit(code)
