#!/usr/bin/env bash
# Installs the Debian packages Kestrel builds with (skipped when all are present), then
# configures and builds a Release tree in build/.
set -euo pipefail
cd "$(dirname "$0")/.."

packages=(cmake g++ make pkg-config libopenexr-dev nlohmann-json3-dev libspdlog-dev libfmt-dev
          libgtest-dev libcli11-dev libpng-dev libbenchmark-dev libhwy-dev libdeflate-dev
          libopencolorio-dev libopenimageio-dev
          pybind11-dev python3-dev python3-numpy python3-pytest python3-matplotlib)
missing=()
for p in "${packages[@]}"; do
  dpkg -s "$p" >/dev/null 2>&1 || missing+=("$p")
done
if ((${#missing[@]})); then
  echo "setup: installing ${missing[*]}"
  sudo=""
  [[ $(id -u) -ne 0 ]] && sudo="sudo"
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi

build_dir=${KESTREL_BUILD_DIR:-build}
cmake -S . -B "$build_dir" -DCMAKE_BUILD_TYPE=Release "$@" >/dev/null
cmake --build "$build_dir" -j"$(nproc)"
