#!/usr/bin/env bash
# Builds the libFuzzer targets (fuzz/) with clang, ASan and UBSan in a separate tree and runs
# each for a bounded time on its seed corpus (fuzz/corpus/<target>/). A crash fails the script;
# the crashing input is left in the build tree's artifacts folder: add it to fuzz/corpus/<target>/
# with a regression test (tests/stability/fuzz_replay_test.cpp replays every corpus file).
#
#   FUZZ_SECONDS          per target (default 60)
#   KESTREL_FUZZ_BUILD_DIR build tree (default build-fuzz)
set -euo pipefail
cd "$(dirname "$0")/.."
seconds=${FUZZ_SECONDS:-60}
build=${KESTREL_FUZZ_BUILD_DIR:-build-fuzz}

# clang and its runtime libraries (libFuzzer, sanitizers): Debian packages.
need=()
command -v clang++ >/dev/null 2>&1 || need+=(clang)
compgen -G "/usr/lib/llvm-*/lib/clang/*/lib/linux/libclang_rt.fuzzer-x86_64.a" >/dev/null ||
  need+=(libclang-rt-14-dev)
dpkg -s libgtest-dev libopenexr-dev libdeflate-dev >/dev/null 2>&1 || bash scripts/setup.sh >/dev/null
if ((${#need[@]})); then
  echo "fuzz: installing ${need[*]}"
  sudo=""
  [[ $(id -u) -ne 0 ]] && sudo="sudo"
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${need[@]}" >/dev/null
fi

t0=$(date +%s)
# -O1, as for the sanitizer suites (scripts/sanitize.sh); fuzz/CMakeLists.txt keeps line tables.
CC=clang CXX=clang++ cmake -S fuzz -B "$build" -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -DNDEBUG" >/dev/null
cmake --build "$build" -j"$(nproc)" --target graph_fuzzer exr_fuzzer
t1=$(date +%s)

export ASAN_OPTIONS="halt_on_error=1:abort_on_error=1:detect_leaks=${KESTREL_ASAN_LEAKS:-1}"
export UBSAN_OPTIONS="halt_on_error=1:print_stacktrace=1"
status=0
run() {  # target, max input length
  local target=$1 maxlen=$2
  local work="$build/corpus/$target" artifacts="$build/artifacts/$target/"
  mkdir -p "$work" "$artifacts"
  echo "fuzz: $target for ${seconds}s (seeds: fuzz/corpus/$target, max_len $maxlen)"
  # New inputs go to the build tree's corpus; the committed seeds are read only.
  # -malloc_limit_mb: no input needs more than a few MB (the EXR target caps windows at 2^16
  # pixels), so one allocation above 256 MB is a finding, reported at the allocation with its
  # stack and the input that made it. Without it the limit is rss_limit_mb (2 GB), and libFuzzer's
  # RSS check, which samples once a second, saves whichever input is running when it notices: the
  # first exr_fuzzer finding was blamed on an input that runs alone in 240 MB (fuzz/FINDINGS.md).
  if ! "$build/$target" "$work" "fuzz/corpus/$target" -max_total_time="$seconds" \
        -max_len="$maxlen" -timeout=10 -rss_limit_mb=2048 -malloc_limit_mb=256 \
        -artifact_prefix="$artifacts" \
        -print_final_stats=1 2>"$build/$target.log"; then
    echo "fuzz: $target FAILED; last lines of $build/$target.log:" >&2
    tail -n 40 "$build/$target.log" >&2
    ls -l "$artifacts" >&2
    status=1
  fi
  grep -E '^stat::(number_of_executed_units|new_units_added|peak_rss_mb)' "$build/$target.log" || true
}
# FUZZ_TARGETS: which targets to run (both are always built).
for target in ${FUZZ_TARGETS:-graph_fuzzer exr_fuzzer}; do
  case $target in
    graph_fuzzer) run graph_fuzzer 32768 ;;
    exr_fuzzer) run exr_fuzzer 20000 ;;
    *) echo "fuzz: unknown target $target" >&2; exit 2 ;;
  esac
done
t2=$(date +%s)
echo "fuzz: build $((t1 - t0)) s, fuzzing $((t2 - t1)) s"
exit $status
