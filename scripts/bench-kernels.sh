#!/usr/bin/env bash
# Per-pass kernel benchmarks (Google Benchmark, 1920x1080, 1 and 2 threads): builds every
# `*_bench` executable of the Release tree and runs it, printing megapixels per second.
# docs/benchmarks.md records the output with the commit and machine.
#   scripts/bench-kernels.sh [FILTER]     (FILTER: a --benchmark_filter regex, default all)
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh >/dev/null
build=${KESTREL_BUILD_DIR:-build}
benches=$(cmake --build "$build" --target help | sed -n 's/^\.\.\. \(.*_bench\)$/\1/p' | sort)
# shellcheck disable=SC2086
cmake --build "$build" -j"$(nproc)" --target $benches >/dev/null
echo "commit $(git rev-parse --short HEAD 2>/dev/null || echo unknown); $(nproc) cores;" \
  "$(sed -n 's/^model name[^:]*: //p' /proc/cpuinfo | head -1); load $(cut -d' ' -f1-3 /proc/loadavg);" \
  "busy clock $(bash scripts/lib/clock-probe.sh) GHz"
for b in $benches; do
  [[ $b == engine_overhead_bench ]] && continue
  "$build/bin/$b" --benchmark_filter="${1:-.}" --benchmark_min_time=1 2>/dev/null |
    grep -E '^(BM_|Benchmark|-)' || true
done
