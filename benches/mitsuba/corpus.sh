#!/usr/bin/env bash
# `lumis import` on public Mitsuba scenes (mitsuba-renderer/mitsuba-data, or with --gallery the
# licensed scenes of docs/gallery.md), each rendered by lumis
# and Mitsuba 3.9.1 and compared (corpus.py). Same environment as race.sh (setup.sh); arguments
# go to corpus.py, e.g. `benches/mitsuba/corpus.sh --data ~/mitsuba-data --only cbox spot`.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
source "$here/setup.sh"

(cd "$repo" && cargo build --release --locked --quiet)
exec "$venv/bin/python" "$here/corpus.py" --lumis "$repo/target/release/lumis" "$@"
