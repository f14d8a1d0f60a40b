#!/usr/bin/env bash
# Whole-graph benchmarks: median ms per frame (loader and writer excluded, loader reported
# separately) of the shipped graphs at 1280x720 and 1920x1080 with 1 and 2 threads, and the peak
# resident memory of each run. Prints a Markdown table; docs/benchmarks.md records its output.
#   scripts/bench.sh [FRAMES]        (default 6 frames, the first 2 left out of the medians)
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh >/dev/null
frames=${1:-6}
kestrel=build/bin/kestrel
work=${KESTREL_BENCH_DIR:-kestrel-out/bench-scenes}
graphs=(svgf svgf-notaa svgf-fast games202-jbf games202-atrous)

echo "commit $(git rev-parse --short HEAD 2>/dev/null || echo unknown); $(nproc) cores;" \
  "$(sed -n 's/^model name[^:]*: //p' /proc/cpuinfo | head -1); load $(cut -d' ' -f1-3 /proc/loadavg)"
echo
echo "| graph | size | threads | ms/frame (median) | loader ms | peak RSS MB | RSS bytes/pixel | busy clock GHz |"
echo "| --- | --- | --- | --- | --- | --- | --- | --- |"
for size in 1280x720 1920x1080; do
  w=${size%x*}; h=${size#*x}
  scene="$work/$size"
  if [[ ! -f "$scene/done" ]]; then
    $kestrel scenegen --out "$scene" --width "$w" --height "$h" --frames "$frames" --spp 1 2>/dev/null
    touch "$scene/done"
  fi
  for g in "${graphs[@]}"; do
    for t in 1 2; do
      out=$($kestrel bench "graphs/$g.json" --input "$scene/noisy/frame_####.exr" --threads "$t" \
              --no-input-row --warmup 2 2>/dev/null)
      row=$(echo "$out" | grep -E "^$g " | head -1)
      ms=$(echo "$row" | awk '{print $(NF-1)}')
      load=$(echo "$row" | awk '{print $NF}')
      rss=$(echo "$out" | sed -n 's/.*peak resident memory of the bench process: \([0-9.]*\) MB.*/\1/p')
      bpp=$(awk -v r="$rss" -v p="$((w * h))" 'BEGIN { printf "%.0f", r * 1048576 / p }')
      echo "| $g | $size | $t | $ms | $load | $rss | $bpp | $(bash scripts/lib/clock-probe.sh) |"
    done
  done
done
