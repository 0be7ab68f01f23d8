#!/usr/bin/env bash
# Two of the performance targets (docs/performance.md), each measured as a ratio of interleaved
# runs: the speed-up from 1 to 2 threads, and the time of `alpha` (integrated) against `balance`
# at equal N. Extra arguments go to ab.py, e.g. `benches/threads.sh --runs 11`.
set -euo pipefail
repo=$(cd "$(dirname "$0")/.." && pwd)
cd "$repo"
cargo build --release --locked --quiet
lumis="$repo/target/release/lumis"
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
echo "machine: $(nproc) cores, $(lscpu | sed -n 's/^Model name: *//p'), load average $(cut -d' ' -f1-3 /proc/loadavg)"

cornell="$lumis render scenes/cornell.ron --set integrator.type=power --set integrator.samples=2 --spp 64 -o $out/c.exr"
echo "Threads: Cornell box 256x256, power, samples 2, 64 spp (speed-up = first/this of 2 threads)"
python3 benches/ab.py "$@" --label "1 thread" --label "2 threads" \
    "$cornell --threads 1" "$cornell --threads 2"
# The wall-time speed-up needs two idle cores; the CPU time of the same runs does not, and tells
# how much work the second thread adds (scheduling, contention): 2 / (this ratio) bounds the
# speed-up an idle machine gives.
echo "CPU time (whole process) of the same runs (ratio = extra work of 2 threads)"
python3 benches/ab.py "$@" --cpu --label "1 thread" --label "2 threads" \
    "$cornell --threads 1" "$cornell --threads 2"

# The Veach layout as in the paper: one camera sample per pixel, N = 64 per light, no AOV.
veach="$lumis render scenes/veach.ron --set integrator.aovs=[] --threads 2 -o $out/v.exr"
echo "alpha (integrated) against balance, Veach layout, N = 64, 1 spp, 2 threads (ratio = alpha/balance)"
python3 benches/ab.py "$@" --label balance --label "alpha integrated" \
    "$veach --set integrator.type=balance" "$veach --set integrator.type=alpha"
