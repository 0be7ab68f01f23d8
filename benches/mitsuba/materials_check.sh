#!/usr/bin/env bash
# Mitsuba's materials (issue 44) against Mitsuba 3.9.1: small XML scenes (plastics, named
# conductors, Beckmann, textures, one-sided surfaces from behind) converted by `lumis import`,
# rendered by both renderers (`direct`, scalar_rgb), mean images compared with the race's block
# test. Same environment as race.sh (setup.sh); arguments go to materials_check.py, e.g.
# `benches/mitsuba/materials_check.sh --runs 8 textured`.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
source "$here/setup.sh"

(cd "$repo" && cargo build --release --locked --quiet)
exec "$venv/bin/python" "$here/materials_check.py" --lumis "$repo/target/release/lumis" "$@"
