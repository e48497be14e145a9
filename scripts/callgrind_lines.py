"""Self instructions of one function, by the source line its inlined code came from.

Usage (see docs/online-speed.md, ninth round):

    CARGO_PROFILE_BENCH_DEBUG=line-tables-only cargo bench --no-run -p prrrp-tests --bench online
    PRRRP_BENCH_CPU_ROWS=1000 PRRRP_BENCH_CPU_CASE=ekf_filter_step valgrind --tool=callgrind \
        --dump-instr=yes --compress-pos=no --compress-strings=no \
        --callgrind-out-file=cg.out target/release/deps/online-HASH --bench
    python3 scripts/callgrind_lines.py cg.out target/release/deps/online-HASH step_avx2 ekf.rs

Each instruction's address is mapped with `addr2line -i` and charged to the innermost
frame in `SOURCE` (the line of ekf.rs a std or intrinsic call was inlined into), and to
that frame's function.
"""

from __future__ import annotations

import collections
import subprocess
import sys


def main(out: str, binary: str, function: str, source: str) -> None:
    costs: collections.Counter[int] = collections.Counter()
    fn = ob = None
    call_line = False
    with open(out) as f:
        for line in f:
            if line.startswith("ob="):
                ob = line[3:].strip()
            elif line.startswith("fn="):
                fn, call_line = line[3:].strip(), False
            elif line.startswith("calls="):
                call_line = True  # the next cost line is the call's inclusive cost
            elif line[:2] == "0x":
                if call_line:
                    call_line = False
                    continue
                parts = line.split()
                mine = fn and function in fn and ob and ob.endswith(binary.split("/")[-1])
                if len(parts) == 3 and mine:
                    costs[int(parts[0], 16)] += int(parts[2])
    total = sum(costs.values())
    addrs = sorted(costs)
    text = subprocess.run(
        ["addr2line", "-a", "-i", "-f", "-C", "-e", binary],
        input="\n".join(hex(a) for a in addrs),
        capture_output=True,
        text=True,
        check=True,
    ).stdout.split("\n")
    frames: dict[int, list[tuple[str, str]]] = {}
    cur, i = None, 0
    while i < len(text):
        if text[i].startswith("0x"):
            cur = int(text[i], 16)
            frames[cur] = []
            i += 1
        elif cur is not None and i + 1 < len(text):
            frames[cur].append((text[i], text[i + 1]))
            i += 2
        else:
            i += 1
    by_line: collections.Counter[str] = collections.Counter()
    by_fn: collections.Counter[str] = collections.Counter()
    for a, c in costs.items():
        hit = next(((f, loc) for f, loc in frames.get(a, []) if source in loc), None)
        if hit:
            by_line[hit[1].split("/")[-1].split(" ")[0]] += c
            by_fn[hit[0].split("::")[-1][:60]] += c
        else:
            by_line["(other)"] += c
    print(f"{function}: {total:,} self instructions")
    for k, c in by_line.most_common(40):
        print(f"{c:>14,} {100 * c / total:5.1f} % {k}")
    print("--- by innermost function in", source)
    for k, c in by_fn.most_common(25):
        print(f"{c:>14,} {100 * c / total:5.1f} % {k}")


if __name__ == "__main__":
    main(*sys.argv[1:5])
