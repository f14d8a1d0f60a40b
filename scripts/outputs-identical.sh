#!/usr/bin/env bash
# Are two builds' outputs bit-identical? Runs every shipped graph on every public sequence
# (../shared/data, where present) and every zoo scene (generated once into a cache folder) with
# an old and a new build, and compares the frames pixel by pixel (NaN equals NaN). A refactor of
# a pass or the engine must leave every line "identical" (or "refused by both").
#
#   scripts/outputs-identical.sh OLD_PREFIX OLD_GRAPHS [NEW_PREFIX NEW_GRAPHS]
#
# A prefix is a folder with bin/kestrel and lib/kestrel/plugins (a build tree, or a copy of its
# bin/ and lib/); NEW defaults to this checkout's build/ and graphs/. Keep an old build with
# `cp -r build/bin build/lib /somewhere/` before changing code: each side runs with
# LD_LIBRARY_PATH at its own lib/ (a build tree's binary has its tree's lib/ as RUNPATH, so a copy
# would otherwise load the tree's current library and plugins).
#   FRAMES      frames of each sequence (default 1-12)
#   GRAPHS      shipped graph names to run (default: every graphs/*.json)
#   SCENES      zoo scene names (default: every zoo scene)
#   ZOO_CACHE   where the zoo scenes are generated (default /tmp/kestrel-zoo)
#   WORK        where outputs go (default: a temporary folder, removed at the end)
# Needs /usr/bin/python3 with numpy and OpenImageIO (Debian: python3-numpy python3-openimageio).
# Exit 0 when every pair is identical, 1 otherwise.
set -uo pipefail
cd "$(dirname "$0")/.."
old=${1:?usage: outputs-identical.sh OLD_PREFIX OLD_GRAPHS [NEW_PREFIX NEW_GRAPHS]}
oldgraphs=${2:?usage: outputs-identical.sh OLD_PREFIX OLD_GRAPHS [NEW_PREFIX NEW_GRAPHS]}
new=${3:-build}
newgraphs=${4:-graphs}
frames=${FRAMES:-1-12}
zoo=${ZOO_CACHE:-/tmp/kestrel-zoo}
work=${WORK:-$(mktemp -d)}
[[ -z ${WORK:-} ]] && trap 'rm -rf "$work"' EXIT
/usr/bin/python3 -c 'import numpy, OpenImageIO' 2>/dev/null ||
  { echo "outputs-identical: needs python3-numpy and python3-openimageio" >&2; exit 2; }

graphs=${GRAPHS:-$(cd "$newgraphs" && ls ./*.json | sed 's|^\./||; s|\.json$||')}
scenes=${SCENES:-"room room-cut room-lamp street street-cloud street-jittered street-static fireflies"}
inputs=()
for s in blender-sample-room blender-street blender-street-defaults blender-showroom; do
  [[ -d ../shared/data/$s ]] && inputs+=("$s|../shared/data/$s/noisy/frame_####.exr|$frames")
done
[[ -d ../shared/data/games202-box ]] && inputs+=("games202-box|../shared/data/games202-box|")
for s in $scenes; do
  if [[ ! -f $zoo/$s/done ]]; then
    "$new/bin/kestrel" scenegen --scene "$s" --out "$zoo/$s" --force >/dev/null ||
      { echo "outputs-identical: scenegen --scene $s failed" >&2; exit 2; }
    touch "$zoo/$s/done"
  fi
  inputs+=("zoo-$s|$zoo/$s/noisy/frame_####.exr|$frames")
done

status=0
for entry in "${inputs[@]}"; do
  IFS='|' read -r name input range <<<"$entry"
  for g in $graphs; do
    fr=()
    [[ -n $range ]] && fr=(--frames "$range")
    LD_LIBRARY_PATH="$old/lib" "$old/bin/kestrel" run "$oldgraphs/$g.json" --input "$input" \
      --output "$work/old/$name/$g/f_####.exr" "${fr[@]}" >/dev/null 2>"$work/err-old"
    a=$?
    LD_LIBRARY_PATH="$new/lib" "$new/bin/kestrel" run "$newgraphs/$g.json" --input "$input" \
      --output "$work/new/$name/$g/f_####.exr" "${fr[@]}" >/dev/null 2>"$work/err-new"
    b=$?
    if ((a != 0 && b != 0)); then
      echo "$name $g: refused by both (exit $a, $b)"
      continue
    elif ((a != 0 || b != 0)); then
      echo "$name $g: DIFFERENT exit codes (old $a, new $b): $(tail -1 "$work/err-new")"
      status=1
      continue
    fi
    /usr/bin/python3 - "$work/old/$name/$g" "$work/new/$name/$g" "$name $g" <<'PY' || status=1
import os, sys
import numpy as np, OpenImageIO as oiio
a, b, label = sys.argv[1:4]
fa = sorted(f for f in os.listdir(a) if f.endswith(".exr"))
fb = sorted(f for f in os.listdir(b) if f.endswith(".exr"))
if fa != fb:
    print(f"{label}: DIFFERENT frame lists ({len(fa)} against {len(fb)})"); sys.exit(1)
def read(path):
    inp = oiio.ImageInput.open(path)
    img, names = inp.read_image(format="float"), inp.spec().channelnames
    inp.close()
    return img, names
worst = 0.0
for f in fa:
    (x, nx), (y, ny) = read(os.path.join(a, f)), read(os.path.join(b, f))
    if nx != ny or x.shape != y.shape:
        print(f"{label}: DIFFERENT channels in {f}: {nx} against {ny}"); sys.exit(1)
    same = (x == y) | (np.isnan(x) & np.isnan(y))
    if not same.all():
        worst = max(worst, float(np.nanmax(np.abs(x - y))))
        worst = worst if worst > 0 else float("nan")
if worst != 0.0:
    print(f"{label}: DIFFERENT pixels, largest difference {worst:.3g}"); sys.exit(1)
print(f"{label}: {len(fa)} frames identical")
PY
  done
done
exit $status
