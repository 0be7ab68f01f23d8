#!/usr/bin/env python3
"""Times lumis commands against each other in interleaved rounds (A B C, A B C, ...), so that a
change in machine load hits every contender alike, and prints each one's median render time (the
"rendered in" of lumis's summary line: the render loop only, without loading or writing; or,
with --cpu, the CPU time of the whole process) with its ratio to the first. Standard library
only.

    benches/ab.py --runs 7 'lumis render s.ron --threads 1' 'lumis render s.ron --threads 2'
"""

import argparse
import re
import resource
import shlex
import statistics
import subprocess
import sys


def render_time(command, cpu):
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    result = subprocess.run(shlex.split(command), capture_output=True, text=True)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if result.returncode != 0:
        sys.exit(f"failed: {command}\n{result.stderr}")
    if cpu:
        return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    found = re.search(r"rendered in ([0-9.]+) s", result.stderr)
    if not found:
        sys.exit(f"no summary line from: {command}\n{result.stderr}")
    return float(found.group(1))


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--runs", type=int, default=7, help="interleaved rounds")
    p.add_argument("--label", action="append", default=[], help="a name per command, in order")
    p.add_argument("--cpu", action="store_true",
                   help="compare the CPU time (user + system) of the whole process instead: on a "
                        "machine shared with other work it varies far less than the wall time")
    p.add_argument("commands", nargs="+")
    args = p.parse_args()
    labels = args.label + args.commands[len(args.label):]
    times = [[] for _ in args.commands]
    for _ in range(args.runs):
        for i, command in enumerate(args.commands):
            times[i].append(render_time(command, args.cpu))
    base = statistics.median(times[0])
    for label, t in zip(labels, times):
        m = statistics.median(t)
        spread = f"{min(t):.3f}..{max(t):.3f}"
        print(f"  {label:32} median {m:7.3f} s  ({spread}, {len(t)} runs)  "
              f"ratio to first {m / base:6.3f}  first/this {base / m:6.3f}")


if __name__ == "__main__":
    main()
