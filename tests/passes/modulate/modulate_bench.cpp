// Modulate at 1920x1080 (illumination, albedo and emission bound, as single.modulate in
// svgf.json). Reports megapixels per second (wall time: the pass runs on its own pool). Built
// as `modulate_bench`, not registered with ctest: run it by hand.
#include <benchmark/benchmark.h>

#include "../PassBench.h"
#include "../demodulate/ModulationTestInputs.h"
#include "ModulatePass.h"
#include "kestrel/testing/PassHarness.h"

namespace {

using namespace kestrel;
using kestrel::testing::PassHarness;

constexpr int kW = 1920, kH = 1080;

void BM_Modulate(benchmark::State& state) {
    static const Image illum = modtest::randomImage(kW, kH, 1, 4.f, 0.f),
                       albedo = modtest::randomImage(kW, kH, 2, 1.f, 0.f),
                       emission = modtest::randomImage(kW, kH, 3, 0.1f, 0.f);
    auto h = PassHarness::make<ModulatePass>({kW, kH}, {}, int(state.range(0)));
    h.bind("illumination", illum);
    h.bind("albedo", albedo);
    h.bind("emission", emission);
    passbench::timeRuns(state, h, "color");
}
KESTREL_PASS_BENCHMARK(BM_Modulate);

}  // namespace

BENCHMARK_MAIN();
