#!/usr/bin/env bash
# The race against Mitsuba 3 (see docs/performance.md): sets up its own Python virtual environment
# (mitsuba 3.9.1, numpy), makes Mitsuba's llvm_ad_rgb variant usable (Debian's libllvm19), builds
# lumis, then checks that the images agree and times both renderers. Arguments go to race.py,
# e.g. `benches/mitsuba/race.sh --scenes cornell --timing-runs 9`.
set -euo pipefail

# Help first: it must not set up anything (no virtual environment, no package, no build).
for arg in "$@"; do
    case "$arg" in
    -h | --help)
        cat <<'EOF'
usage: benches/mitsuba/race.sh [race.py options]

Races lumis against Mitsuba 3 at equal samples (see docs/performance.md): checks that the mean
images agree within their noise, then times both renderers over interleaved runs.

What it sets up on a first run (not for --help): a Python virtual environment in
benches/mitsuba/.venv with mitsuba 3.9.1 and numpy (pip, from PyPI); Debian's libllvm19 when run
as root with apt-get (else Mitsuba's llvm_ad_rgb variant is skipped); a release build of lumis.

Options (passed to race.py):
  --scenes NAME...     cornell dragon veach (default: all)
  --check-runs N       seeds per renderer for the image check (default 6)
  --timing-runs N      interleaved timed runs (default 5)
  --block N            block edge in pixels of the image check (default 16)
  --no-llvm            skip Mitsuba's llvm_ad_rgb variant
  --lumis PATH         the lumis binary (default: target/release/lumis, built by this script)
  --work DIR           working directory (default: target/race)
EOF
        exit 0
        ;;
    esac
done

here=$(cd "$(dirname "$0")" && pwd)
source "$here/setup.sh"

(cd "$repo" && cargo build --release --locked --quiet)
echo "machine: $(nproc) cores, $(lscpu | sed -n 's/^Model name: *//p'), load average $(cut -d' ' -f1-3 /proc/loadavg)"
exec "$venv/bin/python" "$here/race.py" --lumis "$repo/target/release/lumis" "${extra[@]}" "$@"
