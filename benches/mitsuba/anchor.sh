#!/usr/bin/env bash
# Where the render time goes, Mitsuba 3's llvm_ad_rgb against lumis (see anchor.py and
# docs/performance.md). Sets up what race.sh sets up; needs `perf`. Arguments go to anchor.py,
# e.g. `benches/mitsuba/anchor.sh --scenes cornell --runs 9`.
set -euo pipefail
for arg in "$@"; do
    case "$arg" in
    -h | --help)
        cat <<'HELP'
usage: benches/mitsuba/anchor.sh [--scenes NAME...] [--runs N] [--lumis PATH] [--work DIR]

Renders each race scene with Mitsuba's llvm_ad_rgb and with lumis on one thread under
`perf record`, and prints CPU seconds per render split into ray traversal and the rest.
HELP
        exit 0
        ;;
    esac
done
command -v perf >/dev/null || { echo "anchor.sh needs perf (apt-get install linux-perf)" >&2; exit 1; }
here=$(cd "$(dirname "$0")" && pwd)
source "$here/setup.sh"
if [ "${#extra[@]}" -gt 0 ]; then
    echo "anchor.sh needs Mitsuba's llvm_ad_rgb variant (libLLVM 19)" >&2
    exit 1
fi
(cd "$repo" && cargo build --release --locked --quiet)
exec "$venv/bin/python" "$here/anchor.py" --lumis "$repo/target/release/lumis" "$@"
