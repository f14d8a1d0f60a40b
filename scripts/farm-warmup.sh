#!/usr/bin/env bash
# How many warm-up frames does a farm chunk need? For each sequence, runs graphs/svgf.json once
# unsplit and once as a `kestrel farm plan` of two chunks for each warm-up W, and prints the
# relMSE of the second chunk's frames against the unsplit run's (kestrel compare): the largest
# over the chunk's frames, and the first frame's (the largest in practice: history decays).
#
#   bash scripts/farm-warmup.sh                 # build/bin/kestrel, W = 0 1 2 4 8 16
#   KESTREL_BIN=... WARMUPS="0 4 8" bash scripts/farm-warmup.sh
#
# Sequences: the zoo scenes (kestrel scenegen, 40 frames at 96x64, chunks of 24 + 16) and the
# public Blender sequences in ../shared/data (12 frames, chunks of 6 + 6; skipped if absent).
# W at or beyond the split reaches back to the first frame: the chunk then is the unsplit run.
# About three minutes on 2 cores. docs/farm.md holds the table it printed.
set -euo pipefail
cd "$(dirname "$0")/.."

bin=$(realpath "${KESTREL_BIN:-build/bin/kestrel}")
warmups=(${WARMUPS:-0 1 2 4 8 16})
zoo=(${ZOO:-room street street-jittered street-static fireflies})
shared=../shared/data
graph=graphs/svgf.json
threads=2

if [[ ! -x $bin ]]; then
    echo "farm-warmup: no kestrel binary at $bin (build it, or set KESTREL_BIN)" >&2
    exit 1
fi
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

# measure NAME INPUT_PATTERN FRAMES CHUNK: prints one table row.
measure() {
    local name=$1 input=$2 frames=$3 chunk=$4 dir=$tmp/$1
    local last=${frames#*-} split=$((chunk + 1))
    "$bin" run "$graph" --input "$input" --output "$dir/unsplit/frame_####.exr" \
        --frames "$frames" --threads $threads >"$dir.unsplit.log" 2>&1 ||
        { cat "$dir.unsplit.log" >&2; exit 1; }
    local row="| $name | $split-$last |"
    for w in "${warmups[@]}"; do
        "$bin" farm plan "$graph" --input "$input" --output "$dir/w$w/frame_####.exr" \
            --frames "$frames" --chunk "$chunk" --warmup "$w" --format commands \
            --threads $threads >"$dir.plan-$w.sh" 2>/dev/null
        bash "$dir.plan-$w.sh"
        # The table's rows: frame, relMSE, PSNR, SSIM, temporal.
        row+=$("$bin" compare "$dir/w$w/frame_####.exr" "$dir/unsplit/frame_####.exr" \
            --frames "$split-$last" | awk '$1 ~ /^[0-9]+$/ {
                if (n++ == 0) first = $2
                if ($2 + 0 > worst) worst = $2 + 0
            } END { if (worst > 0) printf " %.2e (%.1e) |", worst, first; else printf " 0 |" }')
    done
    echo "$row"
}

header="| sequence | frames compared |"
rule="| --- | --- |"
for w in "${warmups[@]}"; do header+=" W=$w |"; rule+=" --- |"; done
echo "$header"
echo "$rule"
for s in "${zoo[@]}"; do
    mkdir -p "$tmp/zoo-$s"
    "$bin" scenegen --scene "$s" --out "$tmp/scene-$s" --frames 40 --spp 1 --threads $threads \
        >/dev/null 2>&1
    measure "zoo-$s" "$tmp/scene-$s/noisy/frame_####.exr" 1-40 24
done
for d in "$shared"/blender-*/; do
    [[ -d $d/noisy ]] || continue
    s=$(basename "$d")
    mkdir -p "$tmp/$s"
    measure "$s" "$(realpath "$d")/noisy/frame_####.exr" 1-12 6
done
if ! compgen -G "$shared/blender-*/noisy" >/dev/null; then
    echo "(no public sequences: $shared is absent)"
fi
