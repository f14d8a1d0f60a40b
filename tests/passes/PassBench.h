#pragma once
// The timing loop every per-pass Google Benchmark shares: run the bound harness once to
// allocate its outputs, then once per iteration, and report megapixels per second (wall time
// when the benchmark says UseRealTime: the pass runs on its own pool).
#include <benchmark/benchmark.h>

#include <string_view>

#include "kestrel/testing/PassHarness.h"

namespace passbench {

/// Times `h.run()`; `output` is read after each run so the work cannot be optimised away.
inline void timeRuns(benchmark::State& state, kestrel::testing::PassHarness& h,
                     std::string_view output) {
    h.run();  // allocate the outputs
    for (auto _ : state) {
        h.run();
        benchmark::DoNotOptimize(h.out(output).channel(0)[0]);
    }
    const auto& e = h.out(output).extent();
    state.counters["Mpx/s"] =
        benchmark::Counter(double(e.width) * double(e.height) * double(state.iterations()) / 1e6,
                           benchmark::Counter::kIsRate);
}

/// Times two bound harnesses of one pass type either as a fused step (executeFused) or one
/// after the other; both have run once (outputs and scratch allocated).
inline void timePair(benchmark::State& state, kestrel::testing::PassHarness& a,
                     kestrel::testing::PassHarness& b, bool fused, std::string_view output) {
    kestrel::Pass* passes[2] = {&a.pass(), &b.pass()};
    kestrel::PassIO* ios[2] = {&a, &b};
    for (auto _ : state) {
        if (fused) {
            a.pass().executeFused(a.ctx, passes, ios);
        } else {
            a.run();
            b.run();
        }
        benchmark::DoNotOptimize(b.out(output).channel(0)[0]);
    }
}

}  // namespace passbench

/// Registers a per-pass benchmark taking its thread count as state.range(0), with 1 and 2
/// threads, wall time, in milliseconds.
#define KESTREL_PASS_BENCHMARK(fn) \
    BENCHMARK(fn)->Arg(1)->Arg(2)->ArgName("threads")->UseRealTime()->Unit(benchmark::kMillisecond)
