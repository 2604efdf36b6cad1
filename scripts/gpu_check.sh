#!/usr/bin/env bash
# Runs on the GPU host: the gpu-labelled test and a trace benchmark over the
# scenes given, with binaries built elsewhere for sm_90.
# Usage: scripts/gpu_check.sh BIN_DIR LIB_DIR OUT_DIR COMMIT SCENE...
set -uo pipefail
bin=$1 lib=$2 out=$3 commit=$4
shift 4
export LD_LIBRARY_PATH="$lib${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
echo "date:    $(date -u +%Y-%m-%dT%H:%M:%SZ)"
echo "commit:  $commit"
nvidia-smi --query-gpu=name,driver_version,memory.total,clocks.max.sm --format=csv,noheader | sed 's/^/device:  /'
echo "== test_gpu_agreement (label gpu): GPU hits must equal CPU hits bit for bit"
"$bin/test_gpu_agreement" "$@"
echo "test_gpu_agreement exit code: $?"
echo "== as-build / as-trace per scene (GPU, 1920x1080 primary rays, median of 10 launches)"
for scene in "$@"; do
  name=$(basename "$scene"); name=${name%%.*}
  "$bin/as-build" "$scene" -o "/tmp/$name.asf" || continue
  "$bin/as-trace" "/tmp/$name.asf" --device gpu -W 1920 -H 1080 --runs 10 --image "$out/$name.png"
done
