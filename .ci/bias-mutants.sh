#!/usr/bin/env bash
# The named bias mutants of docs/testing.md ("Named bias mutants"): each patch in
# .ci/bias-mutants/ plants one plausible bias; the suite must fail with it. For each patch this
# copies HEAD into a temporary directory, applies the patch there (the source tree is not
# touched), runs the tests given (default: the whole workspace suite) and reports KILLED (some
# test failed) or SURVIVED. Exit status 1 if any mutant survived.
#
#   .ci/bias-mutants.sh                                # every patch, every test (long)
#   .ci/bias-mutants.sh -p lumis --test integration -- integrators::    # every patch, one module
#   PATCHES=".ci/bias-mutants/light-pdf-times-1.02.patch" .ci/bias-mutants.sh --test integration -- render::
set -euo pipefail
cd "$(dirname "$0")/.."
root=$(pwd)
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
# One target directory for every mutant: only the mutated crate and its dependants rebuild.
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$work/target}"
args=("$@")
[ ${#args[@]} -eq 0 ] && args=(--workspace)
survived=0
for patch in ${PATCHES:-$root/.ci/bias-mutants/*.patch}; do
    name=$(basename "$patch" .patch)
    rm -rf "$work/src" && mkdir "$work/src"
    git archive HEAD | tar -x -C "$work/src"
    patch=$(realpath "$patch")
    (cd "$work/src" && git apply "$patch")
    log="$work/$name.log"
    if (cd "$work/src" && cargo test --locked "${args[@]}" >"$log" 2>&1); then
        echo "$name: SURVIVED"
        survived=1
    else
        failed=$(grep -E '^test .* FAILED$' "$log" | sed -E 's/^test (.*) \.\.\. FAILED$/\1/' | tr '\n' ' ')
        echo "$name: KILLED by ${failed:-a build or test failure}"
    fi
done
exit $survived
