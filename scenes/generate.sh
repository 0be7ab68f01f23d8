#!/bin/sh
# Generates the scene assets that are not committed (see scenes/README.md): the MERL-format
# measured BRDFs (35 MB each, git-ignored), tabulated from analytic BSDFs because no measured data
# can be downloaded here. Run from the repository root:
#   scenes/generate.sh
# Builds the release binary (cargo does nothing if it is up to date) and skips files that already
# exist (delete one to regenerate it).
set -eu

if [ ! -f Cargo.toml ] || [ ! -d scenes ]; then
    echo "scenes/generate.sh: run it from the repository root" >&2
    exit 1
fi

cargo build --release --quiet
lumis=target/release/lumis

mkdir -p scenes/measured

# merl NAME BSDF: write scenes/measured/NAME.binary tabulating BSDF, unless it exists.
merl() {
    out="scenes/measured/$1.binary"
    if [ -f "$out" ]; then
        echo "exists:    $out"
    else
        echo "writing:   $out"
        # Written under another name first (still git-ignored), so an interrupted run leaves no
        # truncated file that a later run would skip.
        "$lumis" merl --bsdf "$2" -o "$out.partial.binary"
        mv "$out.partial.binary" "$out"
    fi
}

# scenes/measured.ron and scenes/paper/11.ron
merl copper '(type: "glossy", roughness: 0.15, specular: (0.95, 0.64, 0.54), diffuse: (0.05, 0.03, 0.02))'
# scenes/paper/11.ron
merl acrylic '(type: "glossy", roughness: 0.05, specular: 0.05, diffuse: (0.04, 0.12, 0.4))'
