#!/usr/bin/env bash
# The README's examples do what they say: every code block fenced as ```sh test is run, command by
# command, on a generated scene and on each public sequence in DATA_DIR (../shared/data; skipped
# with a message where absent). A ```json NAME block is written as the file NAME first, so an
# example that reads my-graph.json reads the README's graph.
#
# Each block runs in a fresh folder holding what its commands name: shot/ (the sequence's first
# frames and its camera.json), ref/ (its references), graphs/ and scripts/ (the source's),
# build/bin/kestrel (KESTREL_BIN), and kestrel-out/default-scene (a tiny generated scene standing
# in for the built-in one, so the commands without --input stay quick). What the README writes
# for a user's shot is scaled down, never rewritten otherwise: `--frames A-B` becomes the few
# frames linked, scenegen's size and samples become tiny, `--chunk N` becomes 2. A `blender`
# line is not run (no .blend here): its output folder is the sequence instead.
#
# Asserted: each command exits 0, or N where its comment ends with "exit N"; a command with
# --set gives other pixels than the same command without it (kestrel compare: relMSE > 0), and a
# --sweep of a numeric parameter gives rows with different errors. Commands that read shot/ run on
# every sequence, the others once; a command that needs references is skipped where a sequence
# has none.
#
#   bash tests/cli/readme_examples_test.sh KESTREL_BIN SOURCE_DIR [DATA_DIR]
set -uo pipefail
bin=$(realpath "$1") src=$(realpath "$2") data=${3:-$2/../shared/data}
[[ -d $data ]] && data=$(realpath "$data")
readme=$src/README.md
fail() {
    echo "FAIL: $*"
    exit 1
}
[[ -x $bin ]] || fail "no kestrel binary at $bin"
tmp=$(mktemp -d /tmp/kestrel-readme.XXXXXX)
trap 'rm -rf "$tmp"' EXIT

# --- The README's runnable blocks: one command per line (continuations joined), each block
# starting with a line "@block" ----------------------------------------------------------------
extract_commands() {
    awk '
        /^```sh test/ { inside = 1; print "@block"; next }
        /^```/ { inside = 0; next }
        inside {
            if (sub(/\\[ \t]*$/, "")) { pending = pending $0; next }
            print pending $0; pending = ""
        }' "$readme"
}
# Writes every ```json NAME block into folder $1 as NAME.
write_json_blocks() {
    awk -v dir="$1" '
        /^```json [^ ]+/ { file = dir "/" $2; inside = 1; next }
        /^```/ { inside = 0; next }
        inside { print > file }' "$readme"
}
mapfile -t commands < <(extract_commands)
((${#commands[@]} >= 5)) || fail "only ${#commands[@]} runnable examples found in $readme (\`\`\`sh test blocks)"

# --- Sequences ------------------------------------------------------------------------------------
"$bin" scenegen --out "$tmp/gen" --width 48 --height 32 --frames 4 --spp 16 >"$tmp/gen.log" 2>&1 ||
    fail "scenegen: $(tail -3 "$tmp/gen.log")"
touch "$tmp/gen/complete"  # what ensureDefaultScene leaves in a finished built-in scene

# sequences: "name|noisy folder|reference folder|input pattern|first|last"
sequences=("generated|$tmp/gen/noisy|$tmp/gen/ref|frame_####.exr|1|3")
if [[ -d $data ]]; then
    for s in blender-sample-room blender-showroom blender-street blender-street-defaults; do
        [[ -d $data/$s/noisy ]] && sequences+=("$s|$data/$s/noisy|$data/$s/ref|frame_####.exr|1|2")
    done
    [[ -d $data/games202-box ]] && sequences+=("games202-box|$data/games202-box||beauty_%d.exr|0|1")
else
    echo "SKIP (public sequences): $data not present; the generated scene only"
fi

# A folder for one sequence: links to its frames first..last, camera.json, references.
prepare() {
    local dir=$1 noisy=$2 ref=$3 pattern=$4 first=$5 last=$6
    mkdir -p "$dir/shot" "$dir/build/bin" "$dir/kestrel-out"
    ln -s "$bin" "$dir/build/bin/kestrel"
    ln -s "$src/graphs" "$dir/graphs"
    ln -s "$src/scripts" "$dir/scripts"
    ln -s "$tmp/gen" "$dir/kestrel-out/default-scene"
    write_json_blocks "$dir"
    local f name
    for ((f = first; f <= last; ++f)); do
        for name in "$noisy"/*; do
            # Every file of the frame (GAMES202: beauty_F, normal_F, ..., matrix_F).
            case $(basename "$name") in
            *_$(printf %04d "$f").exr | *_"$f".exr | *_"$f".mat) ln -s "$name" "$dir/shot/" ;;
            esac
        done
        [[ -n $ref ]] && mkdir -p "$dir/ref" &&
            ln -s "$ref/frame_$(printf %04d "$f").exr" "$dir/ref/"
    done
    [[ -f $noisy/../camera.json ]] && ln -s "$noisy/../camera.json" "$dir/shot/camera.json"
    return 0
}

# The README's command scaled down to this sequence (see the header).
scale_down() {
    local cmd=$1 pattern=$2 first=$3 last=$4
    cmd=$(sed -E "s/--frames [0-9]+-[0-9]+/--frames $first-$last/g; s/--chunk [0-9]+/--chunk 2/g" <<<"$cmd")
    if [[ $cmd == *" scenegen "* ]]; then
        cmd=$(sed -E 's/--width [0-9]+/--width 48/; s/--height [0-9]+/--height 32/;
                      s/--frames [0-9]+/--frames 4/; s/--spp [0-9]+/--spp 16/' <<<"$cmd")
    fi
    # The input pattern of a sequence not named frame_####.exr (GAMES202).
    [[ $pattern == frame_####.exr ]] || cmd=$(sed -E "s|--input (shot\|out)/frame_####\.exr|--input \1/$pattern|g" <<<"$cmd")
    echo "$cmd"
}

expected_exit() {
    local comment
    comment=$(grep -oE '[[:space:]]#[[:space:]].*$' <<<"$1")
    [[ $comment =~ exit\ ([0-9]+)[[:space:]]*$ ]] && echo "${BASH_REMATCH[1]}" || echo 0
}

# The first EXR a run wrote below $1 (outside the links), as a #### pattern relative to $1.
written_pattern() {
    local file
    file=$(cd "$1" && find . -path ./kestrel-out/default-scene -prune -o -path ./shot -prune -o \
        -path ./ref -prune -o -name '*.exr' -print | sort | head -1)
    [[ -n $file ]] && sed -E 's/[0-9]{4}\.exr$/####.exr/' <<<"${file#./}"
}

failures=0
ran=0
check() {
    if ! eval "$1"; then
        echo "FAIL [$seq] $2"
        failures=$((failures + 1))
    fi
}

# --set: the same command without the override must give other pixels.
check_set_changes_output() {
    local dir=$1 cmd=$2 plain written metric
    plain=$(sed -E "s/ --set ('[^']*'|[^ ]+)//g" <<<"$cmd")
    prepare "$dir.plain" "$noisy" "$ref" "$pattern" "$first" "$last"
    (cd "$dir.plain" && eval "$plain") >"$dir.plain.log" 2>&1
    written=$(written_pattern "$dir")
    [[ -n $written ]] || {
        echo "FAIL [$seq] $cmd: wrote no EXR to compare"
        failures=$((failures + 1))
        return
    }
    # The largest per-frame relMSE between the two outputs.
    metric=$("$bin" compare "$dir/$written" "$dir.plain/$written" --json 2>/dev/null |
        grep -oE '"relMse": [0-9.eE+-]+' | awk '{ if ($2 > m) m = $2 } END { if (NR) print m + 0 }')
    check '[[ -n $metric ]] && awk -v m="$metric" "BEGIN { exit !(m > 0) }"' \
        "$cmd: the same pixels as without --set (relMSE ${metric:-?}): the override does nothing"
}

# --sweep of numbers: the rows' errors must differ.
check_sweep_changes_output() {
    local dir=$1 cmd=$2 table distinct
    [[ $cmd =~ --sweep\ \'[^=]*=[0-9.]+,[0-9.]+ ]] || return 0
    table=$(find -L "$dir" -path "$dir/kestrel-out/default-scene" -prune -o -name bench.csv -print |
        head -1)
    distinct=$(awk -F, 'NR == 1 { for (i = 1; i <= NF; ++i) if ($i == "relMse") c = i; next }
        c && $1 !~ /^input/ { print $c }' "$table" 2>/dev/null | sort -u | wc -l)
    check '((distinct > 1))' "$cmd: every swept setting gives the same error ($table)"
}

for entry in "${sequences[@]}"; do
    IFS='|' read -r seq noisy ref pattern first last <<<"$entry"
    block=0
    for cmd in "${commands[@]}"; do
        [[ $cmd == @block ]] && block=$((block + 1)) && continue
        [[ -z ${cmd// /} || $cmd =~ ^[[:space:]]*# ]] && continue
        if [[ $seq != generated && $cmd != *shot/* && $cmd != *"--input out/"* &&
            ! $cmd =~ ^blender[[:space:]] ]]; then
            continue  # needs no sequence: run once, on the generated scene
        fi
        if [[ -z $ref && ($cmd == *ref/* || $cmd == *--reference*) ]]; then
            echo "skip [$seq] (no references): $cmd"
            continue
        fi
        dir=$tmp/$seq.$block
        [[ -d $dir ]] || prepare "$dir" "$noisy" "$ref" "$pattern" "$first" "$last"
        if [[ $cmd =~ ^blender[[:space:]] ]]; then
            ln -sfn shot "$dir/out"
            echo "stand-in [$seq]: $cmd (out/ is the sequence)"
            continue
        fi
        run=$(scale_down "$cmd" "$pattern" "$first" "$last")
        want=$(expected_exit "$cmd")
        (cd "$dir" && eval "$run") >"$dir.log" 2>&1
        got=$?
        ran=$((ran + 1))
        if [[ $got != "$want" ]]; then
            echo "FAIL [$seq] $run: exit $got, the README says $want"
            sed 's/^/    /' "$dir.log" | grep -v '^    \[' | tail -5
            failures=$((failures + 1))
            continue
        fi
        echo "ok [$seq] $run (exit $got)"
        [[ $cmd == *--set* ]] && check_set_changes_output "$dir" "$run"
        [[ $cmd == *--sweep* ]] && check_sweep_changes_output "$dir" "$run"
    done
done
((failures == 0)) || fail "$failures of the README's examples do not do what it says"
echo "PASS: $ran runs of the README's examples on ${#sequences[@]} sequences"
