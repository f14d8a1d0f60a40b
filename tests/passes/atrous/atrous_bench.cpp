// One A-Trous iteration at 1920x1080 on a random G-buffer (objects, depth steps, noisy
// radiance), for steps 1 and 16 and 1 or 2 threads. Reports megapixels and taps per second.
// Built as `atrous_bench`, not registered with ctest: scripts/bench-kernels.sh runs it.
#include <benchmark/benchmark.h>

#include "../EquivalenceImages.h"
#include "../PassBench.h"
#include "ATrousPass.h"

namespace {

using namespace kestrel;
using namespace svgftest;
using kestrel::testing::PassHarness;

constexpr int kW = 1920, kH = 1080;

struct Inputs {
    RandomGBuffer g = randomGBuffer(kW, kH, 1);
    Image var = scalar(kW, kH, [](int x, int y) { return 0.01f + 0.1f * hash01(x, y, 9); });
};
const Inputs& inputs() {
    static const Inputs in;
    return in;
}

/// Binds `g` and `var` to an A-Trous pass of `step` on `threads` threads and times its runs.
void runATrous(benchmark::State& state, const RandomGBuffer& g, const Image& var, int step,
               int threads) {
    const Extent size{g.color.width(), g.color.height()};
    auto h = PassHarness::make<ATrousPass>(size, {{"step", int64_t(step)}}, threads);
    h.bind("color", g.color);
    h.bind("variance", var);
    h.bind("depth", g.depth);
    h.bind("normal", g.normal);
    h.bind("objectId", g.ids);
    h.run();  // allocate outputs and scratch
    for (auto _ : state) {
        h.run();
        benchmark::DoNotOptimize(h.out("color").channel(0)[0]);
    }
}

// state.range(0): step; state.range(1): threads.
void BM_ATrous(benchmark::State& state) {
    const Inputs& in = inputs();
    runATrous(state, in.g, in.var, int(state.range(0)), int(state.range(1)));
    const double px = double(kW) * double(kH);
    state.counters["MP/s"] =
        benchmark::Counter(px * 1e-6 * double(state.iterations()), benchmark::Counter::kIsRate);
    state.counters["Gtaps/s"] =
        benchmark::Counter(px * 25e-9 * double(state.iterations()), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_ATrous)
    ->ArgsProduct({{1, 4, 16}, {1, 2}})
    ->ArgNames({"step", "threads"})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime()
    ->MinTime(1.0);

// Two signals on one G-buffer (the diffuse and specular chains of a Blender render): fused
// (Pass::executeFused, the geometric work shared per tap) against two separate passes, in
// one run. state.range(0): step; state.range(1): threads; state.range(2): 1 fused, 0 apart.
void BM_ATrousPair(benchmark::State& state) {
    const Inputs& in = inputs();
    static const RandomGBuffer second = randomGBuffer(kW, kH, 2);  // its colour only
    const Image& color2 = second.color;
    const Extent size{kW, kH};
    const int threads = int(state.range(1));
    const std::map<std::string, ParamValue> params = {{"step", int64_t(state.range(0))}};
    auto a = PassHarness::make<ATrousPass>(size, params, threads);
    auto b = PassHarness::make<ATrousPass>(size, params, threads);
    const Image* colors[2] = {&in.g.color, &color2};
    PassHarness* hs[2] = {&a, &b};
    for (int i = 0; i < 2; ++i) {
        hs[i]->bind("color", *colors[i]);
        hs[i]->bind("variance", in.var);
        hs[i]->bind("depth", in.g.depth);
        hs[i]->bind("normal", in.g.normal);
        hs[i]->bind("objectId", in.g.ids);
        hs[i]->run();  // allocate outputs and scratch
    }
    passbench::timePair(state, a, b, state.range(2) != 0, "color");
}
BENCHMARK(BM_ATrousPair)
    ->ArgsProduct({{1, 16}, {1, 2}, {0, 1}})
    ->ArgNames({"step", "threads", "fused"})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime()
    ->MinTime(1.0);

// Per-pixel cost against the working set: state.range(0) x state.range(1) pixels at step
// state.range(2), 1 thread. A small image's planes stay in L2 between runs, so the difference
// to 1920x1080 is what the memory hierarchy costs (docs/benchmarks.md, roofline notes).
void BM_ATrousSize(benchmark::State& state) {
    const int w = int(state.range(0)), ht = int(state.range(1));
    const RandomGBuffer g = randomGBuffer(w, ht, 1);
    const Image var = scalar(w, ht, [](int x, int y) { return 0.01f + 0.1f * hash01(x, y, 9); });
    runATrous(state, g, var, int(state.range(2)), 1);
    // kInvert of a rate: seconds per pixel, scaled to nanoseconds.
    state.counters["ns/px"] =
        benchmark::Counter(double(w) * double(ht) * double(state.iterations()) * 1e-9,
                           benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
}
BENCHMARK(BM_ATrousSize)
    ->Args({1920, 1080, 1})
    ->Args({512, 64, 1})
    ->Args({256, 32, 1})
    ->Args({1920, 16, 1})
    ->ArgNames({"w", "h", "step"})
    ->UseRealTime()
    ->MinTime(0.3);

}  // namespace

BENCHMARK_MAIN();
