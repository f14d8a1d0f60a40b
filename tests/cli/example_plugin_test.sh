#!/usr/bin/env bash
# End-to-end check of the plugin author's workflow (examples/vignette_pass/README.md):
# install the build tree into a temporary prefix, build the example plugin out of tree against
# it with find_package(Kestrel), and run a graph that uses it with the *installed* kestrel.
#   example_plugin_test.sh <source dir> <build dir>
set -euo pipefail
src=$1
build=$2
work=$(mktemp -d "${TMPDIR:-/tmp}/kestrel-example-test.XXXXXX")
trap 'rm -rf "$work"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }
# No stack dumps or uncaught exceptions in any output.
clean() { ! grep -qE 'terminate called|Segmentation|Aborted|core dumped' "$1" || fail "$1: crash output"; }

prefix=$work/install
cmake --install "$build" --prefix "$prefix" >"$work/install.log" || { cat "$work/install.log"; fail "install"; }
[[ -f $prefix/lib/cmake/Kestrel/KestrelConfig.cmake ]] || fail "no KestrelConfig.cmake installed"
kestrel=$prefix/bin/kestrel
[[ -x $kestrel ]] || fail "no installed kestrel"

# The example builds exactly as its README says (a plain CMake project, no Kestrel source tree).
cmake -S "$src/examples/vignette_pass" -B "$work/example" -DCMAKE_BUILD_TYPE=Release \
    -DCMAKE_PREFIX_PATH="$prefix" >"$work/configure.log" 2>&1 || { cat "$work/configure.log"; fail "configure example"; }
cmake --build "$work/example" -j2 >"$work/build.log" 2>&1 || { cat "$work/build.log"; fail "build example"; }
[[ -f $work/example/vignette.so ]] || fail "no vignette.so"

# The installed kestrel finds its own plugins; KESTREL_PLUGIN_PATH adds the example.
export KESTREL_PLUGIN_PATH=$work/example
"$kestrel" passes --json >"$work/passes.json" 2>"$work/passes.err" || fail "passes"
grep -q '"type": "Vignette"' "$work/passes.json" || fail "Vignette not listed by kestrel passes"
grep -q '"type": "ExrLoader"' "$work/passes.json" || fail "installed ExrLoader not found"

graph=$src/examples/vignette_pass/vignette.json
"$kestrel" validate "$graph" >"$work/validate.out" 2>&1 || { cat "$work/validate.out"; fail "validate"; }
grep -q ': ok' "$work/validate.out" || fail "validate did not say ok"

# A tiny scene as input (32x24, 2 frames).
"$kestrel" scenegen --out "$work/scene" --width 32 --height 24 --frames 2 --spp 4 \
    >"$work/scenegen.log" 2>&1 || { cat "$work/scenegen.log"; fail "scenegen"; }

set +e
"$kestrel" run "$graph" --frames 1-2 --input "$work/scene/noisy/frame_####.exr" \
    --output "$work/out/vignette.####.exr" --out-dir "$work/kout" >"$work/run.log" 2>&1
rc=$?
set -e
clean "$work/run.log"
[[ $rc == 0 ]] || { cat "$work/run.log"; fail "run exited $rc"; }
for f in 1 2; do
    [[ -s $work/out/vignette.000$f.exr ]] || fail "frame $f not written"
done
[[ -z $(find "$work/out" -name '.*tmp*') ]] || fail "temporary files left behind"

# The plugin's declared range is enforced like any shipped pass's: exit 2 naming pass.param.
set +e
"$kestrel" run "$graph" --frames 1 --input "$work/scene/noisy/frame_####.exr" \
    --output "$work/out2/v.####.exr" --set vignette.strength=2 >"$work/range.log" 2>&1
rc=$?
set -e
clean "$work/range.log"
[[ $rc == 2 ]] || { cat "$work/range.log"; fail "out-of-range --set exited $rc, expected 2"; }
grep -q 'vignette.*strength' "$work/range.log" || { cat "$work/range.log"; fail "range error does not name vignette.strength"; }

# Without KESTREL_PLUGIN_PATH the type is unknown: a graph error (exit 2), not a crash.
set +e
KESTREL_PLUGIN_PATH= "$kestrel" validate "$graph" >"$work/noplugin.log" 2>&1
rc=$?
set -e
clean "$work/noplugin.log"
[[ $rc == 2 ]] || { cat "$work/noplugin.log"; fail "unknown type exited $rc, expected 2"; }
grep -q 'Vignette' "$work/noplugin.log" || fail "unknown-type error does not name Vignette"

echo "example plugin: installed, built out of tree, ran 2 frames"
