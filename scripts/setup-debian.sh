#!/usr/bin/env bash
# Installs the Debian 12 packages libas builds with. The CUDA Toolkit is not a
# Debian package: when nvcc is on PATH (or under CUDA_PATH or
# /usr/local/cuda), the CUDA back end is built too.
set -euo pipefail
pkgs=(cmake make gcc g++ pkg-config libzstd-dev zstd libdraco-dev libopenmesh-dev zlib1g-dev libxxhash-dev clang python3 python3-numpy python3-zstandard libembree-dev groff-base)
missing=()
for p in "${pkgs[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if ((${#missing[@]})); then
  sudo=""
  [ "$(id -u)" -eq 0 ] || sudo="sudo"
  echo "setup: installing ${missing[*]}" >&2
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq "${missing[@]}" >/dev/null
fi
