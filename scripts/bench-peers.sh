#!/usr/bin/env bash
# Whole-process speed against a CPU SVGF peer, timed side by side in one run (docs/benchmarks.md):
# Howl144's GAMES202 homework 5 (github.com/Howl144/GAMES202, commit 2493d98, folder
# Assignment5/, a public repository), against `kestrel run graphs/svgf.json` on the same frames
# (GAMES202 layout, EXR in and out, load + compute + write of every frame).
#
#   scripts/bench-peers.sh PEER_SRC [FRAMES] [WIDTHxHEIGHT] [THREADS]
#
# PEER_SRC: a checkout of that repository; its Assignment5/ folder is copied to a work folder
# outside this repository (KESTREL_PEER_WORK, default /tmp/kestrel-peer) and never modified in
# place. Only the copy's main() is replaced, by one that takes input folder, output folder,
# frame count and mode (svgf) from argv and runs the peer's own Denoise loop; the copy is built
# with its own CMakeLists (OpenMP) as a Release build. Defaults: 4 frames, 1920x1080, 2 threads.
set -euo pipefail
cd "$(dirname "$0")/.."
peer_src=${1:?usage: scripts/bench-peers.sh PEER_SRC [FRAMES] [WIDTHxHEIGHT] [THREADS]}
frames=${2:-4}
size=${3:-1920x1080}
threads=${4:-2}
work=${KESTREL_PEER_WORK:-/tmp/kestrel-peer}
w=${size%x*}
h=${size#*x}

if [[ ! -f $peer_src/Assignment5/src/main.cpp ]]; then
    echo "bench-peers: $peer_src/Assignment5/src/main.cpp not found (clone github.com/Howl144/GAMES202)" >&2
    exit 1
fi
bash scripts/setup.sh >/dev/null
kestrel=$PWD/build/bin/kestrel
mkdir -p "$work"

# The peer, built once per work folder.
peer=$work/Assignment5
if [[ ! -x $peer/build/Denoise ]]; then
    rm -rf "$peer"
    cp -r "$peer_src/Assignment5" "$peer"
    # Everything from `int main()` on is replaced; the rest of main.cpp (its loader and its
    # Denoise loop, SVGF) is the peer's own.
    sed -i '/^int main() {/,$d' "$peer/src/main.cpp"
    cat >>"$peer/src/main.cpp" <<'EOF'
// bench-peers.sh: input folder, output folder, frame count and mode from argv.
int main(int argc, char **argv) {
    if (argc != 5 || std::string(argv[4]) != "svgf") {
        std::cerr << "usage: Denoise INPUT_DIR OUTPUT_DIR FRAMES svgf\n";
        return 2;
    }
    Denoise(filesystem::path(argv[1]), filesystem::path(argv[2]), std::stoi(argv[3]));
    return 0;
}
EOF
    cmake -S "$peer" -B "$peer/build" -DCMAKE_BUILD_TYPE=Release >/dev/null
    cmake --build "$peer/build" -j"$(nproc)" >/dev/null
fi

# The frames: the built-in scene in the GAMES202 layout, numbered from 0 as the peer reads them.
scene=$work/scene-$size-$frames
if [[ ! -f $scene/done ]]; then
    rm -rf "$scene"
    "$kestrel" scenegen --out "$scene" --layout games202 --width "$w" --height "$h" \
        --frames "$frames" --first 0 --spp 1 >/dev/null 2>&1
    touch "$scene/done"
fi

seconds() {  # wall seconds of a whole process
    local t0 t1
    t0=$(date +%s.%N)
    "$@" >/dev/null 2>&1
    t1=$(date +%s.%N)
    awk -v a="$t0" -v b="$t1" 'BEGIN { printf "%.2f", b - a }'
}
rm -rf "$work/out-peer" "$work/out-kestrel"
mkdir -p "$work/out-peer" "$work/out-kestrel"
echo "commit $(git rev-parse --short HEAD 2>/dev/null || echo unknown); $(nproc) cores;" \
    "$(sed -n 's/^model name[^:]*: //p' /proc/cpuinfo | head -1); $size, $frames frames," \
    "$threads threads; load $(cut -d' ' -f1-3 /proc/loadavg)"
ours=$(seconds "$kestrel" run graphs/svgf.json --input "$scene" --frames "0-$((frames - 1))" \
    --output "$work/out-kestrel/frame_####.exr" --threads "$threads")
theirs=$(OMP_NUM_THREADS=$threads seconds "$peer/build/Denoise" "$scene" "$work/out-peer" \
    "$frames" svgf)
ours2=$(seconds "$kestrel" run graphs/svgf.json --input "$scene" --frames "0-$((frames - 1))" \
    --output "$work/out-kestrel/frame_####.exr" --threads "$threads")
for f in $(seq 0 $((frames - 1))); do
    [[ -f $work/out-peer/result_$f.exr ]] || { echo "bench-peers: the peer wrote no frame $f" >&2; exit 1; }
done
echo
echo "| program | whole process s ($frames frames) | s per frame | kestrel's speed-up |"
echo "| --- | --- | --- | --- |"
awk -v a="$ours" -v b="$ours2" -v p="$theirs" -v n="$frames" 'BEGIN {
    k = a < b ? a : b
    printf "| kestrel run graphs/svgf.json (best of 2: %.2f, %.2f) | %.2f | %.3f | 1 |\n", a, b, k, k / n
    printf "| Howl144 GAMES202 Assignment5 (svgf) | %.2f | %.3f | %.1fx |\n", p, p / n, p / k
}'
