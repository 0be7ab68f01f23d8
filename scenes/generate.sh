#!/bin/sh
# Generates the scene assets that are not committed: the MERL-format measured BRDFs (35 MB each,
# git-ignored), tabulated from analytic BSDFs by `lumis merl` because no measured data can be
# downloaded here. Run from the repository root:
#   scenes/generate.sh
#
# The commands come from the scenes themselves: every comment line of the form
#   //   cargo run --release -- merl --bsdf '(...)' -o scenes/measured/NAME.binary
# in scenes/*.ron and scenes/paper/*.ron (the same lines the test suite runs), so a scene that
# documents a new asset needs no change here. Builds the release binary first (cargo does nothing
# if it is up to date); skips files that already exist (delete one to regenerate it).
set -eu

if [ ! -f Cargo.toml ] || [ ! -d scenes ]; then
    echo "scenes/generate.sh: run it from the repository root" >&2
    exit 1
fi

cargo build --release --quiet
lumis=target/release/lumis

grep -h '^//   cargo run --release -- merl ' scenes/*.ron scenes/paper/*.ron | sort -u |
while IFS= read -r line; do
    # The arguments after `--`, split as the shell would (the BSDF is in single quotes).
    eval "set -- ${line#*-- }"
    if [ "$#" -ne 5 ] || [ "$1" != merl ] || [ "$2" != --bsdf ] || [ "$4" != -o ]; then
        echo "scenes/generate.sh: cannot read: $line" >&2
        exit 1
    fi
    out=$5
    if [ -f "$out" ]; then
        echo "exists:  $out"
    else
        echo "writing: $out"
        mkdir -p "$(dirname "$out")"
        # Written under another (still git-ignored) name first, so an interrupted run leaves no
        # truncated file that a later run would skip.
        "$lumis" merl --bsdf "$3" -o "$out.partial.binary"
        mv "$out.partial.binary" "$out"
    fi
done
