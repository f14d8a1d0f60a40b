#!/usr/bin/env bash
# How far svgf.json's temporal instability is from the reference's own frame-to-frame noise: for
# every public sequence in ../shared/data and every zoo scene, runs GRAPH (default graphs/svgf.json)
# over frames 1-12 and `kestrel compare --regions` over frames 5-12, and prints a Markdown row:
# the output's temporal instability, the share of the frame where the reference's noise could be
# measured (flat surfaces: src/eval/Regions.h, ReferenceNoise), the noise there (the least temporal
# instability any output can score there), the output's there, and how much lower the whole frame's
# figure could go if the output reached that floor on those pixels and changed nowhere else.
#
#   bash scripts/flicker-floor.sh [GRAPH]     # a few minutes on 2 cores
set -euo pipefail
cd "$(dirname "$0")/.."

bin=${KESTREL_BIN:-build/bin/kestrel}
graph=${1:-graphs/svgf.json}
shared=../shared/data
public=(blender-sample-room blender-street blender-street-defaults)
zoo=(room room-cut street street-jittered street-static street-cloud fireflies)
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

row() {
    local name=$1 dir=$2
    "$bin" run "$graph" --input "$dir/noisy/frame_####.exr" --output "$tmp/out/$name/frame_####.exr" \
        --frames 1-12 --threads 2 >"$tmp/run.log" 2>&1 || { cat "$tmp/run.log" >&2; exit 1; }
    "$bin" compare "$tmp/out/$name/frame_####.exr" "$dir/ref/frame_####.exr" --frames 5-12 \
        --regions "$dir/noisy/frame_####.exr" 2>/dev/null |
        awk -v scene="$name" '
            $1 == "all" && NF >= 6 { all = $NF }
            /^reference.s own noise/ {
                match($0, /estimated on [0-9.]+%/); share = substr($0, RSTART + 13, RLENGTH - 14) / 100
                match($0, /\(flat\): [0-9.]+/); floor = substr($0, RSTART + 8, RLENGTH - 8)
                match($0, /output.s [0-9.]+/); out = substr($0, RSTART + 9, RLENGTH - 9)
            }
            END {
                if (share == "") { printf "| %s | %.5f | - | - | - | - |\n", scene, all; exit }
                printf "| %s | %.5f | %.1f%% | %.5f | %.5f (%.2fx) | %.1f%% |\n", scene, all, \
                    100 * share, floor, out, out / floor, 100 * share * (out - floor) / all
            }'
}

echo "| sequence | temporal instability | measured on | reference noise there | output there | at most lower by |"
echo "| --- | --- | --- | --- | --- | --- |"
for s in "${public[@]}"; do
    [[ -e $shared/$s/noisy/frame_0001.exr ]] && row "$s" "$shared/$s"
done
for s in "${zoo[@]}"; do
    "$bin" scenegen --scene "$s" --out "$tmp/zoo/$s" --threads 2 >/dev/null 2>&1
    row "zoo $s" "$tmp/zoo/$s"
done
