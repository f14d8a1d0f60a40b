#!/usr/bin/env bash
# How far svgf.json's temporal instability is from the reference's own frame-to-frame noise: for
# every public sequence in ../shared/data and every zoo scene, runs GRAPH (default graphs/svgf.json)
# over frames 1-12 and `kestrel compare --regions` over frames 5-12, and prints a Markdown row:
# the output's temporal instability, the share of the frame where the reference's noise could be
# measured (flat surfaces of point-sampled renders: src/eval/Regions.h, ReferenceNoise), the
# noise there (about the least temporal instability any output can score there), the output's
# there, and how much lower the whole frame's figure could go if the output reached that floor on
# those pixels and changed nowhere else.
#
#   bash scripts/flicker-floor.sh [GRAPH]     # a minute on 2 cores
#   bash scripts/flicker-floor.sh --check     # the estimate against a measurement: zoo scenes
#                                             # rendered twice (seeds 1, 2), one reference compared
#                                             # with the other on the same pixels (their change
#                                             # differs by sqrt(2) x the noise of one)
set -euo pipefail
cd "$(dirname "$0")/.."

bin=${KESTREL_BIN:-build/bin/kestrel}
shared=../shared/data
public=(blender-sample-room blender-street blender-street-defaults)
zoo=(room room-cut street street-jittered street-static street-cloud fireflies)
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

# quiet LOG CMD...: runs CMD, showing its output only if it fails.
quiet() {
    local log=$1
    shift
    "$@" >"$log" 2>&1 || { cat "$log" >&2; exit 1; }
}

# regions OUT REF INPUT: the region table of frames 5-12.
regions() {
    quiet "$tmp/compare.log" "$bin" compare "$1" "$2" --frames 5-12 --regions "$3"
    cat "$tmp/compare.log"
}

# The "all" row's temporal instability, and the reference-noise line's share, floor and output.
parse='
    $1 == "all" && NF >= 6 { all = $6 }
    /^reference.s own noise/ {
        match($0, /estimated on [0-9.]+%/); share = substr($0, RSTART + 13, RLENGTH - 14) / 100
        match($0, /\(flat\): [0-9.]+/); floor = substr($0, RSTART + 8, RLENGTH - 8)
        match($0, /output.s [0-9.]+/); out = substr($0, RSTART + 9, RLENGTH - 9)
    }'

row() {
    local name=$1 dir=$2
    quiet "$tmp/run.log" "$bin" run "$graph" --input "$dir/noisy/frame_####.exr" \
        --output "$tmp/out/$name/frame_####.exr" --frames 1-12 --threads 2
    regions "$tmp/out/$name/frame_####.exr" "$dir/ref/frame_####.exr" "$dir/noisy/frame_####.exr" |
        awk -v scene="$name" "$parse"'
            END {
                if (share == "") { printf "| %s | %.5f | - | - | - | - |\n", scene, all; exit }
                printf "| %s | %.5f | %.1f%% | %.5f | %.5f (%.2fx) | %.1f%% |\n", scene, all, \
                    100 * share, floor, out, out / floor, 100 * share * (out - floor) / all
            }'
}

check() {
    echo "| zoo scene | measured on | estimated | measured (two references) | estimate / measured |"
    echo "| --- | --- | --- | --- | --- |"
    for s in room street-static street; do
        for seed in 1 2; do
            quiet "$tmp/scenegen.log" "$bin" scenegen --scene "$s" --seed "$seed" \
                --out "$tmp/$s-$seed" --threads 2
        done
        regions "$tmp/$s-2/ref/frame_####.exr" "$tmp/$s-1/ref/frame_####.exr" \
            "$tmp/$s-1/noisy/frame_####.exr" |
            awk -v scene="$s" "$parse"'
                END { m = out / sqrt(2)
                      printf "| %s | %.1f%% | %.5f | %.5f | %.3f |\n", scene, 100 * share, floor, m, floor / m }'
    done
}

if [[ ${1:-} == --check ]]; then
    check
    exit 0
fi
graph=${1:-graphs/svgf.json}
echo "| sequence | temporal instability | measured on | reference noise there | output there | at most lower by |"
echo "| --- | --- | --- | --- | --- | --- |"
for s in "${public[@]}"; do
    [[ -e $shared/$s/noisy/frame_0001.exr ]] && row "$s" "$shared/$s"
done
for s in "${zoo[@]}"; do
    quiet "$tmp/scenegen.log" "$bin" scenegen --scene "$s" --out "$tmp/zoo/$s" --threads 2
    row "zoo $s" "$tmp/zoo/$s"
done
