#!/usr/bin/env bash
# The done-when check of `lumis import` (issue 18): a Mitsuba 3 XML scene with an OBJ mesh, a
# rough conductor, an area light and an env map is converted by `lumis import`, rendered by both
# renderers (Mitsuba 3.9.1 `direct`, scalar_rgb) and their mean images compared with the race's
# block test. Same environment as race.sh (setup.sh); arguments go to import_check.py, e.g.
# `benches/mitsuba/import_check.sh --runs 8`.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
source "$here/setup.sh"

(cd "$repo" && cargo build --release --locked --quiet)
exec "$venv/bin/python" "$here/import_check.py" --lumis "$repo/target/release/lumis" "$@"
