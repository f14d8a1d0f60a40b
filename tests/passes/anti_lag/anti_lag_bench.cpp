// AntiLag at 1920x1080 (random HDR-ish colour and history, 3% fireflies, a valid history on 90%
// of the pixels), radius 4 (svgf.json's). Reports megapixels per second (wall time: the pass
// runs on its own pool). Built as `anti_lag_bench`, not registered with ctest: run it by hand
// or through scripts/bench-kernels.sh.
#include <benchmark/benchmark.h>

#include <cmath>
#include <random>

#include "../PassBench.h"
#include "AntiLagPass.h"
#include "kestrel/testing/PassHarness.h"

namespace {

using namespace kestrel;
using kestrel::testing::PassHarness;

constexpr int kW = 1920, kH = 1080;

struct Inputs {
    Image color{kW, kH, Format::Float3}, history{kW, kH, Format::Float3},
        length{kW, kH, Format::Float};
    Inputs() {
        std::mt19937 rng(1);
        std::uniform_real_distribution<float> u(0.f, 1.f);
        for (int c = 0; c < 3; ++c)
            for (size_t i = 0; i < color.extent().pixels(); ++i) {
                color.channel(c)[i] = u(rng) * u(rng) * (u(rng) < 0.03f ? 100.f : 1.f);
                history.channel(c)[i] = 0.25f + 0.1f * u(rng);
            }
        for (size_t i = 0; i < color.extent().pixels(); ++i)
            length.channel(0)[i] = u(rng) < 0.1f ? 0.f : std::floor(1.f + 31.f * u(rng));
    }
};

const Inputs& inputs() {
    static const Inputs in;
    return in;
}

void BM_AntiLag(benchmark::State& state) {
    const auto& in = inputs();
    auto h = PassHarness::make<AntiLagPass>({kW, kH}, {}, int(state.range(0)));
    h.bind("color", in.color);
    h.bind("history", in.history);
    h.bind("historyLength", in.length);
    passbench::timeRuns(state, h, "historyLength");
}
KESTREL_PASS_BENCHMARK(BM_AntiLag);

}  // namespace

BENCHMARK_MAIN();
