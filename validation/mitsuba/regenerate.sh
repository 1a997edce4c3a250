#!/usr/bin/env bash
# Regenerates the Mitsuba 3 references (references.json) on a fresh Debian 12 machine:
# installs libLLVM 19 (Dr.Jit's LLVM backend), a virtual environment with the pinned packages
# (requirements.txt), builds spibench, then exports and renders every case.
#   bash validation/mitsuba/regenerate.sh                 # all cases
#   bash validation/mitsuba/regenerate.sh --only paper_bench --scale 0.1
# Nothing here runs in `cargo test`; the test suite only reads references.json.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
root="$(cd "$here/../.." && pwd)"
if ! ldconfig -p | grep -q 'libLLVM.so.19\|libLLVM-19'; then
    if [ "$(id -u)" = 0 ]; then
        apt-get update -qq && apt-get install -y -qq libllvm19
    else
        echo "libLLVM 19 is missing: run 'sudo apt-get install -y libllvm19' first" >&2
        exit 1
    fi
fi
venv="${MITSUBA_VENV:-$here/.venv}"
if [ ! -x "$venv/bin/python" ]; then
    python3 -m venv "$venv"
fi
"$venv/bin/pip" install -q -r "$here/requirements.txt"
(cd "$root" && cargo build --quiet --bin spibench)
exec "$venv/bin/python" "$here/run_references.py" --spibench "$root/target/debug/spibench" "$@"
