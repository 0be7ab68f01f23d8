#!/usr/bin/env bash
# Sourced by race.sh and import_check.sh (after they set `here`): the Python virtual environment
# with mitsuba 3.9.1 and numpy in $venv, and Mitsuba's llvm_ad_rgb variant made usable with
# Debian's libllvm19 where possible; `extra` holds --no-llvm when it is not.
repo=$(cd "$here/../.." && pwd)
venv="$here/.venv"

if [ ! -x "$venv/bin/python" ]; then
    python3 -m venv "$venv"
fi
if ! "$venv/bin/python" -c 'import mitsuba, numpy' 2>/dev/null; then
    "$venv/bin/pip" install --quiet mitsuba==3.9.1 numpy
fi

# Dr.Jit's LLVM backend needs a recent libLLVM (15 miscompiles Mitsuba's kernels).
llvm=(/usr/lib/x86_64-linux-gnu/libLLVM-19.so /usr/lib/x86_64-linux-gnu/libLLVM.so.19*)
if [ ! -e "${llvm[0]}" ] && [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null; then
    echo "installing Debian's libllvm19 for Mitsuba's llvm_ad_rgb variant"
    # A fresh machine's package lists may be empty: fetched once, only when the install fails.
    apt-get install -y -qq libllvm19 >/dev/null 2>&1 ||
        { apt-get update -qq >/dev/null && apt-get install -y -qq libllvm19 >/dev/null 2>&1; } || true
fi
extra=()
if [ -e "${llvm[0]}" ]; then
    export DRJIT_LIBLLVM_PATH="${llvm[0]}"
else
    echo "skipping Mitsuba llvm_ad_rgb: libLLVM 19 is not installed (apt-get install libllvm19)"
    extra=(--no-llvm)
fi
