"""Ctrl-C and SIGTERM for the command line: a run that receives one ends with 130 / 143 and
writes nothing, even when the signal lands where Python ignores exceptions.

Python runs a signal handler at whatever bytecode it is executing. When that is a weakref
callback or a finaliser, the handler's ``KeyboardInterrupt`` is printed as "Exception
ignored" and dropped, and the run went on to finish with exit code 0 (seen once in CI under
CPU load). The handlers here also remember the signal; :func:`checkpoint` raises it again at
the places where the run continues or commits output (progress reports, before an output
folder or file is swapped in, and when a command returns).
"""

from __future__ import annotations

import contextlib
import signal
from collections.abc import Iterator
from types import FrameType
from typing import NoReturn

_received: int | None = None


def _raise_for(signum: int) -> NoReturn:
    if signum == signal.SIGINT:
        raise KeyboardInterrupt
    # An exception, unlike the default action, unwinds: temporary output is removed and
    # running computations stop (the bindings poll for signals).
    raise SystemExit(128 + signum)


def _on_signal(signum: int, _frame: FrameType | None) -> None:
    global _received
    _received = signum
    _raise_for(signum)


def install() -> None:
    """Handles SIGINT and SIGTERM as described in the module docs (main thread only;
    elsewhere the handlers are left as they are), forgetting a signal of an earlier run in
    this process."""
    reset()
    with contextlib.suppress(ValueError):  # not the main thread
        signal.signal(signal.SIGINT, _on_signal)
        signal.signal(signal.SIGTERM, _on_signal)


def ignore() -> None:
    """Ignores further SIGINT and SIGTERM (main thread only): for a run that is already
    ending for one, whose exit handlers (multiprocessing's joins) a second Ctrl-C turned
    into a traceback on stderr."""
    with contextlib.suppress(ValueError):  # not the main thread
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        signal.signal(signal.SIGTERM, signal.SIG_IGN)


def received() -> int | None:
    """The signal the run received, if any."""
    return _received


def checkpoint() -> None:
    """Raises again a signal received earlier (KeyboardInterrupt for SIGINT, SystemExit
    128 + n otherwise); does nothing when none was, or when :func:`install` was not called."""
    if _received is not None:
        _raise_for(_received)


def reset() -> None:
    """Forgets a received signal (for a caller that handled it and goes on)."""
    global _received
    _received = None


@contextlib.contextmanager
def deferred() -> Iterator[None]:
    """Holds SIGINT and SIGTERM back (on this thread) inside the block; one that arrived
    meanwhile is handled as the block ends, its exception raised from the end of the
    ``with``. For steps that create something and record it, e.g. a temporary file and its
    name: interrupted between the two, the cleanup would not know the file. Without
    ``signal.pthread_sigmask`` (not POSIX) the block runs as it is."""
    if not hasattr(signal, "pthread_sigmask"):
        yield
        return
    mask = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT, signal.SIGTERM})
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, mask)  # runs a handler, which may raise
