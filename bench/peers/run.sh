#!/usr/bin/env bash
# portalview against Mitsuba 3 on the built-in scenes (see mitsuba_bench.py). Makes a virtual
# environment in bench/peers/.venv with Mitsuba 3.9 from PyPI, builds portalview, and runs the
# benchmark; arguments go to mitsuba_bench.py. `run.sh rays [ARGS]` runs mitsuba_rays.py instead
# (raw traversal of the same rays in both renderers). Mitsuba's llvm_ad_rgb variant needs LLVM's
# shared library: Debian's libllvm19 (installed here when missing and running as root).
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
root="$(cd "$here/../.." && pwd)"
llvm=/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1
if [ ! -e "${DRJIT_LIBLLVM_PATH:-$llvm}" ]; then
    if [ "$(id -u)" = 0 ]; then
        apt-get update -qq && apt-get install -y -qq libllvm19
    else
        echo "Mitsuba's llvm_ad_rgb needs libLLVM: apt-get install libllvm19, or set DRJIT_LIBLLVM_PATH" >&2
        exit 1
    fi
fi
export DRJIT_LIBLLVM_PATH="${DRJIT_LIBLLVM_PATH:-$llvm}"
venv="$here/.venv"
if [ ! -x "$venv/bin/python" ]; then
    python3 -m venv "$venv"
fi
"$venv/bin/pip" install -q 'mitsuba==3.9.*' numpy
if [ -z "${PORTALVIEW:-}" ]; then
    (cd "$root" && cargo build --release)
    PORTALVIEW="$root/target/release/portalview"
fi
script=mitsuba_bench.py
if [ "${1:-}" = rays ]; then
    script=mitsuba_rays.py
    shift
fi
exec "$venv/bin/python" "$here/$script" --portalview "$PORTALVIEW" "$@"
