#!/usr/bin/env bash
# Runs on the GPU host: the gpu-labelled test and a trace benchmark over the
# scenes given, with binaries built elsewhere for sm_90.
# Usage: scripts/gpu_check.sh BIN_DIR LIB_DIR OUT_DIR COMMIT SCENE[@EYE@TARGET@UP@FOV]...
# (a scene without a camera is traced with the default camera)
set -uo pipefail
bin=$1 lib=$2 out=$3 commit=$4
shift 4
export LD_LIBRARY_PATH="$lib${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
echo "date:    $(date -u +%Y-%m-%dT%H:%M:%SZ)"
echo "commit:  $commit"
nvidia-smi --query-gpu=name,driver_version,memory.total,clocks.max.sm --format=csv,noheader | sed 's/^/device:  /'
echo "== test_gpu_agreement (label gpu): GPU hits must equal CPU hits bit for bit"
scenes=()
for arg in "$@"; do scenes+=("${arg%%@*}"); done
"$bin/test_gpu_agreement" "${scenes[@]}"
echo "test_gpu_agreement exit code: $?"
echo "== as-build / as-trace per scene (GPU, 1920x1080 primary rays, median of 10 launches)"
for arg in "$@"; do
  scene=${arg%%@*}
  camera=()
  if [ "$arg" != "$scene" ]; then
    IFS=@ read -r _ eye target up fov <<<"$arg"
    camera=(--eye "$eye" --target "$target" --up "$up" --fov "$fov")
  fi
  name=$(basename "$scene"); name=${name%%.*}
  "$bin/as-build" "$scene" -o "/tmp/$name.asf" || continue
  "$bin/as-trace" "/tmp/$name.asf" --device gpu -W 1920 -H 1080 --runs 10 "${camera[@]}" --image "$out/$name.png"
  "$bin/as-trace" "/tmp/$name.asf" --device cpu -W 1920 -H 1080 "${camera[@]}" | grep -E "^(device|trace|Mrays)"
done
