#!/usr/bin/env bash
# Two build trees side by side (e.g. a portable one and -DKESTREL_NATIVE=ON): svgf.json's median
# ms per frame at 1920x1080 with 2 threads (`kestrel bench`, loader and writer excluded), the
# trees alternating round after round in one run, and the minimum over the rounds of each. The
# machine is shared and its clock moves (docs/benchmarks.md), so only the minimum of
# alternating runs compares the builds.
#   scripts/bench-builds.sh BUILD_A BUILD_B [ROUNDS] [GRAPH]   (default 5 rounds, svgf)
# The built-in scene (6 frames, 1 spp) is generated once under KESTREL_BENCH_DIR.
set -euo pipefail
cd "$(dirname "$0")/.."
a=${1:?usage: bench-builds.sh BUILD_A BUILD_B [ROUNDS] [GRAPH]}
b=${2:?usage: bench-builds.sh BUILD_A BUILD_B [ROUNDS] [GRAPH]}
rounds=${3:-5}
graph=${4:-svgf}
scene=${KESTREL_BENCH_DIR:-kestrel-out/bench-scenes}/1920x1080
if [[ ! -f "$scene/done" ]]; then
  "$a/bin/kestrel" scenegen --out "$scene" --width 1920 --height 1080 --frames 6 --spp 1 2>/dev/null
  touch "$scene/done"
fi
echo "commit $(git rev-parse --short HEAD 2>/dev/null || echo unknown); $(nproc) cores;" \
  "$(sed -n 's/^model name[^:]*: //p' /proc/cpuinfo | head -1); load $(cut -d' ' -f1-3 /proc/loadavg)"
declare -A best
for ((r = 1; r <= rounds; r++)); do
  for build in "$a" "$b"; do
    row=$("$build/bin/kestrel" bench "graphs/$graph.json" --input "$scene/noisy/frame_####.exr" \
            --threads 2 --no-input-row --warmup 2 --rounds 1 2>/dev/null | grep -E "^$graph " | head -1)
    ms=$(awk '{print $(NF-1)}' <<<"$row")
    echo "round $r $build: $ms ms/frame (busy clock $(bash scripts/lib/clock-probe.sh) GHz)"
    if [[ -z ${best[$build]:-} ]] || awk -v m="$ms" -v b="${best[$build]}" 'BEGIN { exit !(m < b) }'; then
      best[$build]=$ms
    fi
  done
done
for build in "$a" "$b"; do echo "minimum $build: ${best[$build]} ms/frame"; done
