#!/usr/bin/env bash
# The race against Mitsuba 3 (see docs/performance.md): sets up its own Python virtual environment
# (mitsuba 3.9.1, numpy), makes Mitsuba's llvm_ad_rgb variant usable (Debian's libllvm19), builds
# lumis, then checks that the images agree and times both renderers. Arguments go to race.py,
# e.g. `benches/mitsuba/race.sh --scenes cornell --timing-runs 9`.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
source "$here/setup.sh"

(cd "$repo" && cargo build --release --locked --quiet)
echo "machine: $(nproc) cores, $(lscpu | sed -n 's/^Model name: *//p'), load average $(cut -d' ' -f1-3 /proc/loadavg)"
exec "$venv/bin/python" "$here/race.py" --lumis "$repo/target/release/lumis" "${extra[@]}" "$@"
