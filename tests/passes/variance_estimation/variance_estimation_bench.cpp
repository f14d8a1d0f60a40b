// VarianceEstimation at 1920x1080: every pixel with a short history (the first frames of a
// sequence, the worst case: a 7x7 bilateral at every pixel) and about 10% short (steady state
// with disocclusions), 1 or 2 threads. Reports megapixels per second.
// Built as `variance_estimation_bench`, not registered with ctest: scripts/bench-kernels.sh.
#include <benchmark/benchmark.h>

#include "../EquivalenceImages.h"
#include "../PassBench.h"
#include "VarianceEstimationPass.h"

namespace {

using namespace kestrel;
using namespace svgftest;
using kestrel::testing::PassHarness;

constexpr int kW = 1920, kH = 1080;

struct BenchInputs {
    RandomGBuffer g = randomGBuffer(kW, kH, 2);
    Image moments{kW, kH, Format::Float2};
    Image var = constant(kW, kH, Format::Float, 0.1f);
    BenchInputs() {
        for (int y = 0; y < kH; ++y)
            for (int x = 0; x < kW; ++x) {
                moments.at(0, x, y) = hash01(x, y, 3);
                moments.at(1, x, y) = moments.at(0, x, y) * moments.at(0, x, y) * 1.5f;
            }
    }
};

const BenchInputs& benchInputs() {
    static const BenchInputs in;
    return in;
}

/// Short history in 8x4 blobs, like disocclusions behind moving objects (seed: which blobs).
Image shortBlobs(float fraction, int seed) {
    return scalar(kW, kH,
                  [&](int x, int y) { return hash01(x / 8, y / 4, seed) < fraction ? 1.f : 8.f; });
}

PassHarness harness(const Image& length, int threads) {
    const BenchInputs& in = benchInputs();
    auto h = PassHarness::make<VarianceEstimationPass>({kW, kH}, {}, threads);
    h.bind("color", in.g.color);
    h.bind("moments", in.moments);
    h.bind("historyLength", length);
    h.bind("variance", in.var);
    h.bind("depth", in.g.depth);
    h.bind("normal", in.g.normal);
    h.bind("objectId", in.g.ids);
    h.run();
    return h;
}

// state.range(0): percentage of pixels with a short history; state.range(1): threads.
void BM_VarianceEstimation(benchmark::State& state) {
    const Image length = shortBlobs(float(state.range(0)) / 100.f, 4);
    PassHarness h = harness(length, int(state.range(1)));
    for (auto _ : state) {
        h.run();
        benchmark::DoNotOptimize(h.out("color").channel(0)[0]);
    }
    state.counters["MP/s"] = benchmark::Counter(double(kW) * kH * 1e-6 * double(state.iterations()),
                                                benchmark::Counter::kIsRate);
}

// Two chains on one G-buffer (the split's diffuse and specular): run as a fused pair
// (executeFused), state.range(2) = 1, or one after the other, 0. Their short pixels differ
// (other blobs), as anti-lag shortens each chain's history on its own.
void BM_VarianceEstimationTwoChains(benchmark::State& state) {
    const float fraction = float(state.range(0)) / 100.f;
    const Image lengthA = shortBlobs(fraction, 4), lengthB = shortBlobs(fraction, 5);
    PassHarness a = harness(lengthA, int(state.range(1))),
                b = harness(lengthB, int(state.range(1)));
    passbench::timePair(state, a, b, state.range(2) != 0, "color");
}

BENCHMARK(BM_VarianceEstimation)
    ->ArgsProduct({{100, 10, 0}, {1, 2}})
    ->ArgNames({"short%", "threads"})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime()
    ->MinTime(1.0);
BENCHMARK(BM_VarianceEstimationTwoChains)
    ->ArgsProduct({{100, 10}, {2}, {0, 1}})
    ->ArgNames({"short%", "threads", "fused"})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime()
    ->MinTime(1.0);

}  // namespace

BENCHMARK_MAIN();
