// Reprojection at 1920x1080 on the synthetic scene of ReprojectionScene.h (moving discs over a
// panning background: ~90% of 8-pixel groups share one integer tap offset, as in the shipped
// bench scene). Reports megapixels per second (wall time: the pass runs on its own pool).
// Built as `reprojection_bench`, not registered with ctest: run it by hand.
#include <benchmark/benchmark.h>

#include <string>

#include "../PassBench.h"
#include "ReprojectionPass.h"
#include "ReprojectionScene.h"
#include "kestrel/testing/PassHarness.h"

namespace {

using namespace kestrel;
using kestrel::testing::PassHarness;

constexpr int kW = 1920, kH = 1080;

const reprojscene::Frames& frames() {
    static const reprojscene::Frames f = reprojscene::makeFrames(kW, kH, 1);
    return f;
}

// state.range(0): threads; state.range(1): 0 = SVGF (bilinear, colour + moments + length),
// 1 = TAA history as svgf.json has it (Catmull-Rom, colour, its age and resampleBlur, without
// the depth/normal tests), 2 = the same with the tests.
void BM_Reprojection(benchmark::State& state) {
    const auto& f = frames();
    const bool taa = state.range(1) != 0, tests = state.range(1) != 1;
    auto h = PassHarness::make<ReprojectionPass>(
        {kW, kH},
        {{"filter", std::string(taa ? "catmullrom" : "bilinear")}, {"geometryTests", tests}},
        int(state.range(0)));
    h.bind("depth", f.depth);
    h.bind("normal", f.normal);
    h.bind("objectId", f.objectId);
    h.bind("motion", f.motion);
    h.bind("prevDepth", f.prevDepth);
    h.bind("prevNormal", f.prevNormal);
    h.bind("prevObjectId", f.prevObjectId);
    h.bind("prevColor", f.prevColor);
    h.bind("prevHistoryLength", f.prevHistoryLength);
    if (!taa)
        h.bind("prevMoments", f.prevMoments);
    else
        h.useOutputs({"color", "historyLength", "resampleBlur"});
    passbench::timeRuns(state, h, "color");
    state.SetLabel(!taa    ? "bilinear (single.reprojection)"
                   : tests ? "catmullrom, depth/normal tests"
                           : "catmullrom, no depth/normal tests (taaReprojection)");
}
BENCHMARK(BM_Reprojection)
    ->ArgsProduct({{1, 2}, {0, 1, 2}})
    ->ArgNames({"threads", "taa"})
    ->UseRealTime()
    ->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
