#!/usr/bin/env python3
"""Times lumis commands against each other in interleaved rounds (A B C, A B C, ...), so that a
change in machine load hits every contender alike, and prints each one's median render time (the
"rendered in" of lumis's summary line: the render loop only, without loading or writing; or,
with --cpu, the CPU time of the whole process) with its ratio to the first and that ratio's 95 %
confidence interval (from the rounds' paired ratios). Standard library only.

    benches/ab.py --runs 7 'lumis render s.ron --threads 1' 'lumis render s.ron --threads 2'
"""

import argparse
import math
import re
import resource
import shlex
import statistics
import subprocess
import sys


# Two-sided 95 % quantiles of Student's t by degrees of freedom (beyond 30: the normal's).
T_975 = {1: 12.706, 2: 4.303, 3: 3.182, 4: 2.776, 5: 2.571, 6: 2.447, 7: 2.365, 8: 2.306,
         9: 2.262, 10: 2.228, 11: 2.201, 12: 2.179, 13: 2.160, 14: 2.145, 15: 2.131, 16: 2.120,
         17: 2.110, 18: 2.101, 19: 2.093, 20: 2.086, 21: 2.080, 22: 2.074, 23: 2.069, 24: 2.064,
         25: 2.060, 26: 2.056, 27: 2.052, 28: 2.048, 29: 2.045, 30: 2.042}


def ratio_interval(numerators, denominators):
    """The ratio of two paired series of times (round i of one against round i of the other,
    interleaved so that a change of load hits both) as the geometric mean of the per-round
    ratios, with a 95 % confidence interval from Student's t on their logarithms: (ratio, low,
    high); low and high are None with fewer than 2 rounds."""
    logs = [math.log(a / b) for a, b in zip(numerators, denominators)]
    mean = statistics.fmean(logs)
    if len(logs) < 2:
        return math.exp(mean), None, None
    half = T_975.get(len(logs) - 1, 1.96) * statistics.stdev(logs) / math.sqrt(len(logs))
    return math.exp(mean), math.exp(mean - half), math.exp(mean + half)


def fmt_ratio(ratio, low, high):
    """`1.067 [1.031, 1.104]`, or the ratio alone without an interval."""
    return f"{ratio:.3f}" if low is None else f"{ratio:.3f} [{low:.3f}, {high:.3f}]"


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
    for label, t in zip(labels, times):
        m = statistics.median(t)
        spread = f"{min(t):.3f}..{max(t):.3f}"
        print(f"  {label:32} median {m:7.3f} s  ({spread}, {len(t)} runs)  "
              f"first/this {fmt_ratio(*ratio_interval(times[0], t))}")


if __name__ == "__main__":
    main()
