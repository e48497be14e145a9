"""Soak test of the main job: `prrrp reproduce` N times beside two CPU hogs, each run with
a deadline, then N Ctrl-C's mid-run, each answered within a second (the issue's check of the
deadlock fix). Not part of CI (minutes); run it on a change to threads, locks or callbacks:

    .venv/bin/python scripts/soak_reproduce.py --runs 30
"""

from __future__ import annotations

import argparse
import random
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--runs", type=int, default=30)
    parser.add_argument("--deadline", type=float, default=120.0, help="s per reproduction")
    args = parser.parse_args()
    hogs = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(2)]
    failures = 0
    try:
        with tempfile.TemporaryDirectory() as tmp:
            for k in range(args.runs):
                out = Path(tmp) / f"run{k}"
                cmd = [sys.executable, "-m", "prrrp", "reproduce", "--out", str(out)]
                t0 = time.monotonic()
                try:
                    r = subprocess.run(cmd, capture_output=True, text=True, timeout=args.deadline)
                    ok = r.returncode == 0 and (out / "results.json").is_file()
                    what = f"exit {r.returncode}"
                except subprocess.TimeoutExpired:
                    ok, what = False, "HUNG"
                failures += not ok
                print(f"reproduce {k + 1}/{args.runs}: {what}, {time.monotonic() - t0:.1f} s")
            for k in range(args.runs):
                out = Path(tmp) / f"int{k}"
                child = subprocess.Popen(
                    [sys.executable, "-m", "prrrp", "reproduce", "--out", str(out)],
                    stdout=subprocess.DEVNULL,
                    stderr=subprocess.DEVNULL,
                )
                time.sleep(random.Random(k).uniform(0.5, 4.0))
                child.send_signal(signal.SIGINT)
                t0 = time.monotonic()
                try:
                    code = child.wait(timeout=30)
                except subprocess.TimeoutExpired:
                    child.kill()
                    code = None
                took = time.monotonic() - t0
                leftovers = [p.name for p in Path(tmp).iterdir() if p.name.startswith(".int")]
                # A run that finished before the signal is fine (exit 0 and a full folder);
                # one interrupted while Python still imports dies of the signal (-2, which a
                # shell reports as 130, like our exit code).
                stopped = code in (130, -signal.SIGINT) and took < 1.0
                ok = (stopped and not out.exists() and not leftovers) or (
                    code == 0 and (out / "results.json").is_file()
                )
                failures += not ok
                print(f"Ctrl-C {k + 1}/{args.runs}: exit {code} after {took:.2f} s {leftovers}")
    finally:
        for h in hogs:
            h.kill()
    print("FAILED" if failures else "all passed", f"({failures} failures)")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
