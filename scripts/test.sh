#!/usr/bin/env bash
# Builds libas and runs the whole test suite (CPU; GPU tests skip without a GPU).
# Usage: scripts/test.sh [BUILD_DIR]
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
build="${1:-$root/build}"
"$root/scripts/setup-debian.sh"
. "$root/scripts/env.sh"
cmake -S "$root" -B "$build" -DCMAKE_BUILD_TYPE=Release ${AS_CMAKE_ARGS:-} >/dev/null
cmake --build "$build" -j "$(nproc)"
cd "$build"
ctest --output-on-failure -j "$(nproc)" -LE large
