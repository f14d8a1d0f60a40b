// TemporalAccumulation at 1920x1080 (random HDR-ish colour with 3% fireflies, valid history
// on 90% of the pixels). Reports megapixels per second (wall time: the pass runs on its own
// pool). Built as `temporal_accumulation_bench`, not registered with ctest: run it by hand.
#include <benchmark/benchmark.h>

#include <cmath>
#include <random>

#include "../PassBench.h"
#include "TemporalAccumulationPass.h"
#include "kestrel/testing/PassHarness.h"

namespace {

using namespace kestrel;
using kestrel::testing::PassHarness;

constexpr int kW = 1920, kH = 1080;

struct Inputs {
    Image color{kW, kH, Format::Float3}, prevColor{kW, kH, Format::Float3},
        prevMoments{kW, kH, Format::Float2}, prevLength{kW, kH, Format::Float};
    Inputs() {
        std::mt19937 rng(1);
        std::uniform_real_distribution<float> u(0.f, 1.f);
        for (int c = 0; c < 3; ++c)
            for (size_t i = 0; i < color.extent().pixels(); ++i) {
                color.channel(c)[i] = u(rng) * u(rng) * (u(rng) < 0.03f ? 100.f : 1.f);
                prevColor.channel(c)[i] = 0.5f * u(rng);
            }
        for (size_t i = 0; i < color.extent().pixels(); ++i) {
            prevMoments.channel(0)[i] = 0.4f * u(rng);
            prevMoments.channel(1)[i] = 0.3f * u(rng);
            prevLength.channel(0)[i] = u(rng) < 0.1f ? 0.f : std::floor(1.f + 31.f * u(rng));
        }
    }
};

const Inputs& inputs() {
    static const Inputs in;
    return in;
}

void BM_TemporalAccumulation(benchmark::State& state) {
    const auto& in = inputs();
    auto h = PassHarness::make<TemporalAccumulationPass>({kW, kH}, {}, int(state.range(0)));
    h.bind("color", in.color);
    h.bind("prevColor", in.prevColor);
    h.bind("prevMoments", in.prevMoments);
    h.bind("prevHistoryLength", in.prevLength);
    passbench::timeRuns(state, h, "color");
}
KESTREL_PASS_BENCHMARK(BM_TemporalAccumulation);

}  // namespace

BENCHMARK_MAIN();
