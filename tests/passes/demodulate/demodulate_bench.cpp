// Demodulate at 1920x1080 (colour, albedo and emission bound, as in svgf.json). Reports
// megapixels per second (wall time: the pass runs on its own pool). Built as
// `demodulate_bench`, not registered with ctest: run it by hand.
#include <benchmark/benchmark.h>

#include "../PassBench.h"
#include "DemodulatePass.h"
#include "ModulationTestInputs.h"
#include "kestrel/testing/PassHarness.h"

namespace {

using namespace kestrel;
using kestrel::testing::PassHarness;

constexpr int kW = 1920, kH = 1080;

void BM_Demodulate(benchmark::State& state) {
    static const Image color = modtest::randomImage(kW, kH, 1, 4.f, 0.f),
                       albedo = modtest::randomImage(kW, kH, 2, 1.f, 0.f),
                       emission = modtest::randomImage(kW, kH, 3, 0.1f, 0.f);
    auto h = PassHarness::make<DemodulatePass>({kW, kH}, {}, int(state.range(0)));
    h.bind("color", color);
    h.bind("albedo", albedo);
    h.bind("emission", emission);
    passbench::timeRuns(state, h, "illumination");
}
KESTREL_PASS_BENCHMARK(BM_Demodulate);

}  // namespace

BENCHMARK_MAIN();
