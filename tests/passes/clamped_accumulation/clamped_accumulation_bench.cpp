// ClampedAccumulation at 1920x1080 with the GAMES202 graphs' parameters (7x7 window; random
// HDR-ish colour and history, 10% failed projections). Reports megapixels per second (wall
// time: the pass runs on its own pool). Built as `clamped_accumulation_bench`, not registered
// with ctest: run it by hand.
#include <benchmark/benchmark.h>

#include <random>

#include "../PassBench.h"
#include "ClampedAccumulationPass.h"
#include "kestrel/testing/PassHarness.h"

namespace {

using namespace kestrel;
using kestrel::testing::PassHarness;

constexpr int kW = 1920, kH = 1080;

struct Inputs {
    Image cur{kW, kH, Format::Float3}, hist{kW, kH, Format::Float3}, len{kW, kH, Format::Float};
    Inputs() {
        std::mt19937 rng(1);
        std::uniform_real_distribution<float> u(0.f, 1.f);
        for (int c = 0; c < 3; ++c)
            for (size_t i = 0; i < cur.extent().pixels(); ++i) {
                cur.channel(c)[i] = 2.f * u(rng) * u(rng);
                hist.channel(c)[i] = cur.channel(c)[i] * (0.8f + 0.4f * u(rng));
            }
        for (size_t i = 0; i < len.extent().pixels(); ++i)
            len.channel(0)[i] = u(rng) < 0.1f ? 0.f : 1.f;
    }
};

void BM_ClampedAccumulation(benchmark::State& state) {
    static const Inputs in;
    auto h = PassHarness::make<passes::ClampedAccumulationPass>({kW, kH}, {}, int(state.range(0)));
    h.bind("color", in.cur);
    h.bind("history", in.hist);
    h.bind("historyLength", in.len);
    passbench::timeRuns(state, h, "color");
}
KESTREL_PASS_BENCHMARK(BM_ClampedAccumulation);

}  // namespace

BENCHMARK_MAIN();
