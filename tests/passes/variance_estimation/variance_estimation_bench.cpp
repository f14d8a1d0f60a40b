// VarianceEstimation at 1920x1080: every pixel with a short history (the first frames of a
// sequence, the worst case: a 7x7 bilateral at every pixel) and about 10% short (steady state
// with disocclusions), 1 or 2 threads. Reports megapixels per second.
// Built as `variance_estimation_bench`, not registered with ctest: scripts/bench-kernels.sh.
#include <benchmark/benchmark.h>

#include "../EquivalenceImages.h"
#include "VarianceEstimationPass.h"

namespace {

using namespace kestrel;
using namespace svgftest;
using kestrel::testing::PassHarness;

constexpr int kW = 1920, kH = 1080;

// state.range(0): percentage of pixels with a short history; state.range(1): threads.
void BM_VarianceEstimation(benchmark::State& state) {
    static const RandomGBuffer g = randomGBuffer(kW, kH, 2);
    static const Image moments = [] {
        Image m(kW, kH, Format::Float2);
        for (int y = 0; y < kH; ++y)
            for (int x = 0; x < kW; ++x) {
                m.at(0, x, y) = hash01(x, y, 3);
                m.at(1, x, y) = m.at(0, x, y) * m.at(0, x, y) * 1.5f;
            }
        return m;
    }();
    static const Image var = constant(kW, kH, Format::Float, 0.1f);
    const float shortFraction = float(state.range(0)) / 100.f;
    // Short history in 8x4 blobs, like disocclusions behind moving objects.
    const Image length = scalar(
        kW, kH, [&](int x, int y) { return hash01(x / 8, y / 4, 4) < shortFraction ? 1.f : 8.f; });
    auto h = PassHarness::make<VarianceEstimationPass>({kW, kH}, {}, int(state.range(1)));
    h.bind("color", g.color);
    h.bind("moments", moments);
    h.bind("historyLength", length);
    h.bind("variance", var);
    h.bind("depth", g.depth);
    h.bind("normal", g.normal);
    h.bind("objectId", g.ids);
    h.run();
    for (auto _ : state) {
        h.run();
        benchmark::DoNotOptimize(h.out("color").channel(0)[0]);
    }
    state.counters["MP/s"] = benchmark::Counter(double(kW) * kH * 1e-6 * double(state.iterations()),
                                                benchmark::Counter::kIsRate);
}
BENCHMARK(BM_VarianceEstimation)
    ->ArgsProduct({{100, 10}, {1, 2}})
    ->ArgNames({"short%", "threads"})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime()
    ->MinTime(1.0);

}  // namespace

BENCHMARK_MAIN();
