#!/usr/bin/env bash
# The main job on the bundled bunny: import, build, inspect, trace to a PNG.
# Traces on the GPU when there is one, else on every CPU core.
# Usage: scripts/demo.sh [BUILD_DIR]   (writes demo/bunny.asf and demo/bunny.png)
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
build="${1:-$root/build}"
"$root/scripts/setup-debian.sh"
. "$root/scripts/env.sh"
cmake -S "$root" -B "$build" -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build "$build" -j "$(nproc)" --target as-build as-inspect as-trace
out="$root/demo"
mkdir -p "$out"
set -x
"$build/tools/as-build" "$root/scenes/bunny.drc" -o "$out/bunny.asf"
"$build/tools/as-inspect" "$out/bunny.asf" --validate
"$build/tools/as-trace" "$out/bunny.asf" --width 1024 --height 768 --image "$out/bunny.png"
