"""The one Ctrl-C harness of the test suite: run a call in a child process (which gets a real
SIGINT, as from a terminal), interrupt it once it has started, and check that it stopped with
KeyboardInterrupt promptly instead of running to the end."""

from __future__ import annotations

import signal
import subprocess
import sys
import textwrap
import time


def assert_ctrl_c_stops(call: str, setup: str = "", *, after: float = 1.0, limit: float = 20.0):
    """Runs `setup` then `call` (Python source, `prrrp`, `np` imported) in a child, sends
    SIGINT `after` seconds after the call started and asserts that the child caught
    KeyboardInterrupt within `limit` seconds (exit 130, not "finished")."""
    script = textwrap.dedent(
        """
        import sys, time
        import numpy as np
        import prrrp
        {setup}
        print("started", flush=True)
        t0 = time.monotonic()
        try:
            {call}
        except KeyboardInterrupt:
            print(f"interrupted after {{time.monotonic() - t0:.2f}} s", flush=True)
            sys.exit(130)
        print("finished", flush=True)
        """
    ).format(setup=textwrap.dedent(setup).strip(), call=call)
    child = subprocess.Popen(
        [sys.executable, "-c", script], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    try:
        assert child.stdout.readline().strip() == "started", child.stderr.read()
        time.sleep(after)
        child.send_signal(signal.SIGINT)
        out, err = child.communicate(timeout=limit)
    finally:
        child.kill()
    assert child.returncode == 130, (out, err)
    assert "interrupted" in out
