#!/usr/bin/env bash
# The bench report in a real browser: benches a tiny generated scene, renders bench.html in
# Debian's headless chromium and reads what the page's own check (the script at the end of
# bench.html) wrote into <body data-label-check=...>: "ok N" when it measured N labels and no two
# overlap, else the overlapping pairs; data-images (decoded/all) and data-flip (the A/B picture
# flips on a click). Fails when the page does not render, a label overlaps another, a crop does
# not decode or the flip does not work; exit 77 (ctest SKIP_RETURN_CODE) where chromium is not
# installed.
#
#   bash tests/cli/report_browser_test.sh KESTREL_BIN SOURCE_DIR
set -uo pipefail
bin=$1 src=$2
skip() {
    echo "SKIP: $*"
    exit 77
}
fail() {
    echo "FAIL: $*"
    exit 1
}
browser=$(command -v chromium || command -v chromium-browser || command -v google-chrome) ||
    skip "chromium not found (Debian: apt-get install chromium)"

tmp=$(mktemp -d /tmp/kestrel-report.XXXXXX)
trap 'rm -rf "$tmp"' EXIT
cd "$tmp" || fail "cannot enter $tmp"
"$bin" scenegen --width 32 --height 24 --frames 4 --out scene >scenegen.log 2>&1 ||
    fail "scenegen: $(tail -3 scenegen.log)"
# Several settings of one graph close together (the labels that used to print over each
# other) and the unfiltered input row.
"$bin" bench "$src/graphs/svgf.json" "$src/graphs/svgf-fast.json" --input 'scene/noisy/frame_####.exr' --reference 'scene/ref/frame_####.exr' \
    --sweep '*.atrous0.sigmaL=2,4,8,16' --warmup 1 --threads 1 --report report \
    >bench.log 2>&1 || fail "bench: $(tail -5 bench.log)"
[[ -s report/bench.html ]] || fail "no report/bench.html"

# --virtual-time-budget lets the page's load handler run before the DOM is dumped.
timeout 60 "$browser" --headless --no-sandbox --disable-gpu --virtual-time-budget=5000 \
    --dump-dom "file://$tmp/report/bench.html" >dom.html 2>browser.log ||
    fail "chromium did not render the page: $(tail -3 browser.log)"
check=$(grep -o 'data-label-check="[^"]*"' dom.html | head -1)
[[ -n $check ]] || fail "the page's label check did not run (no data-label-check in the DOM)"
echo "$check"
[[ $check == 'data-label-check="ok '* ]] || fail "labels overlap: $check"
n=${check#*ok }
n=${n%\"}
((n >= 5)) || fail "only $n labels measured: the plots did not render"
images=$(grep -o 'data-images="[^"]*"' dom.html | head -1)
images=${images#*=\"}
images=${images%\"}
[[ -n $images && ${images%/*} == "${images#*/}" && ${images#*/} -gt 0 ]] ||
    fail "crop images not all decoded: ${images:-no data-images in the DOM}"
grep -q 'data-flip="ok"' dom.html || fail "the A/B picture does not flip on a click"
echo "PASS: bench.html rendered in $(basename "$browser"), $n labels, none overlapping;" \
    "$images images decoded; the A/B flip works"
