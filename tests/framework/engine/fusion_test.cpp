// Fusion (Pass::executeFused): passes of one type that share their fuseOn inputs and fusion key,
// none depending on another, run as one step. The step's memory is planned as one: nothing a
// member still reads is given to another member's output.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>
#include <string>
#include <vector>

#include "TestPasses.h"

namespace kestrel::enginetest {
namespace {

/// Two chains of two Guided passes (keys 1 then 2) on one guide, summed.
const char* kTwoChains = R"({"kestrel": 1, "passes": [
    {"name": "ramp", "type": "Ramp"}, {"name": "a", "type": "AddOne"},
    {"name": "b", "type": "NeighbourAverage"},
    {"name": "a1", "type": "Guided", "params": {"key": 1}},
    {"name": "a2", "type": "Guided", "params": {"key": 2}},
    {"name": "b1", "type": "Guided", "params": {"key": 1}},
    {"name": "b2", "type": "Guided", "params": {"key": 2}},
    {"name": "sum", "type": "Sum"}],
  "edges": [{"from": "ramp.out", "to": ["a.in", "b.in", "a1.guide", "a2.guide", "b1.guide", "b2.guide"]},
    {"from": "a.out", "to": "a1.in"}, {"from": "a1.out", "to": "a2.in"},
    {"from": "b.out", "to": "b1.in"}, {"from": "b1.out", "to": "b2.in"},
    {"from": "a2.out", "to": "sum.a"}, {"from": "b2.out", "to": "sum.b"}],
  "outputs": ["sum.out"]})";

std::vector<float> runOnce(CompiledGraph& g) {
    Parallel par(1);
    Executor ex(g, par, {}, {11, 4});
    ex.runFrame(1);
    ImageView out = ex.output("sum.out");
    return {out.channel(0), out.channel(0) + out.pixels()};
}

/// Resources alive in overlapping steps never share a plane.
void expectNoSharedLivePlanes(const CompiledGraph& g) {
    const auto& res = g.resources();
    for (size_t i = 0; i < res.size(); ++i)
        for (size_t j = i + 1; j < res.size(); ++j) {
            if (res[i].history || res[j].history) continue;
            if (res[j].inPlaceOf == int(i) || res[i].inPlaceOf == int(j)) continue;
            if (res[i].firstUse > res[j].lastUse || res[j].firstUse > res[i].lastUse) continue;
            for (int p : res[i].planes)
                for (int q : res[j].planes)
                    EXPECT_NE(p, q) << res[i].producer << " and " << res[j].producer;
        }
}

/// Runs `fused` and the graph `json` compiled without fusion; both give the same output to the
/// bit, and `fused` makes `fusedCalls` executeFused calls in its frame.
void expectSameResultAsUnfused(CompiledGraph& fused, const char* json, const Registry& r,
                               int fusedCalls) {
    CompileOptions apart;
    apart.fuse = false;
    auto separate = compileGraph(parseGraph(json), r, apart);
    EXPECT_TRUE(separate->report().fused.empty());
    GuidedPass::fusedCalls = 0;
    const std::vector<float> a = runOnce(fused);
    EXPECT_EQ(GuidedPass::fusedCalls, fusedCalls);
    GuidedPass::fusedCalls = 0;
    const std::vector<float> b = runOnce(*separate);
    EXPECT_EQ(GuidedPass::fusedCalls, 0);
    ASSERT_EQ(a.size(), b.size());
    EXPECT_EQ(std::memcmp(a.data(), b.data(), a.size() * sizeof(float)), 0);
}

TEST(Fusion, IndependentPassesWithOneGuideRunAsOneStepWithTheSameResult) {
    Registry r = testRegistry();
    auto fused = compileText(kTwoChains, r);

    const auto& groups = fused->report().fused;
    ASSERT_EQ(groups.size(), 2u);
    EXPECT_EQ(groups[0], (std::vector<std::string>{"a1", "b1"}));
    EXPECT_EQ(groups[1], (std::vector<std::string>{"a2", "b2"}));
    const auto order = fused->executionOrder();
    for (const auto& group : groups) {  // adjacent, one step
        const auto at = std::find(order.begin(), order.end(), group[0]) - order.begin();
        EXPECT_EQ(order[size_t(at) + 1], group[1]);
        EXPECT_EQ(fused->stepOf(size_t(at)), fused->stepOf(size_t(at) + 1));
    }
    expectNoSharedLivePlanes(*fused);
    EXPECT_NE(fused->toDot().find("a1\\n(Guided)\\nfused with b1"), std::string::npos);
    expectSameResultAsUnfused(*fused, kTwoChains, r, 2);
}

TEST(Fusion, DependentPassesOrDifferentGuidesAreNotFused) {
    Registry r = testRegistry();
    // p feeds q: one key, one guide, but q needs p's output.
    auto chained = compileText(R"({"kestrel": 1, "passes": [
        {"name": "ramp", "type": "Ramp"},
        {"name": "p", "type": "Guided", "params": {"key": 1}},
        {"name": "q", "type": "Guided", "params": {"key": 1}}],
      "edges": [{"from": "ramp.out", "to": ["p.in", "p.guide", "q.guide"]},
        {"from": "p.out", "to": "q.in"}], "outputs": ["q.out"]})",
                               r);
    EXPECT_TRUE(chained->report().fused.empty());
    // Two guides.
    auto guides = compileText(R"({"kestrel": 1, "passes": [
        {"name": "ramp", "type": "Ramp"}, {"name": "g", "type": "AddOne"},
        {"name": "p", "type": "Guided", "params": {"key": 1}},
        {"name": "q", "type": "Guided", "params": {"key": 1}}, {"name": "sum", "type": "Sum"}],
      "edges": [{"from": "ramp.out", "to": ["g.in", "p.in", "q.in", "p.guide"]},
        {"from": "g.out", "to": "q.guide"},
        {"from": "p.out", "to": "sum.a"}, {"from": "q.out", "to": "sum.b"}],
      "outputs": ["sum.out"]})",
                              r);
    EXPECT_TRUE(guides->report().fused.empty());
}

TEST(Fusion, GroupsThatWouldWaitForEachOtherLeaveTheLaterOneOut) {
    Registry r = testRegistry();
    // {p, s} and {q, r}: p feeds q and r feeds s, so the two steps would each wait for the
    // other; the later group is left out and {p, s} runs fused, after r and before q.
    const char* crossed = R"({"kestrel": 1, "passes": [
        {"name": "ramp", "type": "Ramp"},
        {"name": "p", "type": "Guided", "params": {"key": 1}},
        {"name": "q", "type": "Guided", "params": {"key": 2}},
        {"name": "r", "type": "Guided", "params": {"key": 2}},
        {"name": "s", "type": "Guided", "params": {"key": 1}}, {"name": "sum", "type": "Sum"}],
      "edges": [{"from": "ramp.out", "to": ["p.in", "r.in", "p.guide", "q.guide", "r.guide", "s.guide"]},
        {"from": "p.out", "to": "q.in"}, {"from": "r.out", "to": "s.in"},
        {"from": "q.out", "to": "sum.a"}, {"from": "s.out", "to": "sum.b"}],
      "outputs": ["sum.out"]})";
    auto cycle = compileText(crossed, r);
    ASSERT_EQ(cycle->report().fused.size(), 1u);
    EXPECT_EQ(cycle->report().fused[0], (std::vector<std::string>{"p", "s"}));
    const auto order = cycle->executionOrder();
    auto at = [&](const char* name) { return std::find(order.begin(), order.end(), name); };
    EXPECT_LT(at("r"), at("s"));
    EXPECT_LT(at("p"), at("q"));
    expectSameResultAsUnfused(*cycle, crossed, r, 1);
}

// Passes whose consumed outputs differ are not fused: each step's members produce the same.
TEST(Fusion, PassesWithDifferentConsumedOutputsAreNotFused) {
    Registry r = testRegistry();
    auto g = compileText(R"({"kestrel": 1, "passes": [
        {"name": "ramp", "type": "Ramp"},
        {"name": "p", "type": "Guided", "params": {"key": 1}},
        {"name": "q", "type": "Guided", "params": {"key": 1}}, {"name": "sink", "type": "Sink"}],
      "edges": [{"from": "ramp.out", "to": ["p.in", "q.in", "p.guide", "q.guide"]},
        {"from": "p.out", "to": "sink.in"}],
      "outputs": ["q.out", "q.aux"]})",
                         r);
    EXPECT_TRUE(g->report().fused.empty());
}

// A type that handles absent outputs in executeFused fuses them anyway, with the same results.
TEST(Fusion, ATypeThatAllowsItFusesPassesWithDifferentConsumedOutputs) {
    Registry r = testRegistry();
    // q's aux is marked, p's is not: Guided would not fuse them (the test above).
    const char* text = R"({"kestrel": 1, "passes": [
        {"name": "ramp", "type": "Ramp"},
        {"name": "p", "type": "GuidedAnyOutputs", "params": {"key": 1}},
        {"name": "q", "type": "GuidedAnyOutputs", "params": {"key": 1}}, {"name": "sum", "type": "Sum"}],
      "edges": [{"from": "ramp.out", "to": ["p.in", "q.in", "p.guide", "q.guide"]},
        {"from": "p.out", "to": "sum.a"}, {"from": "q.out", "to": "sum.b"}],
      "outputs": ["sum.out", "q.aux"]})";
    auto g = compileText(text, r);
    ASSERT_EQ(g->report().fused.size(), 1u);
    EXPECT_EQ(g->report().fused[0], (std::vector<std::string>{"p", "q"}));
    expectSameResultAsUnfused(*g, text, r, 1);
}

// A failure in a fused step names every pass of it: any of them may have failed.
TEST(Fusion, AFailingFusedStepNamesItsPasses) {
    Registry r = testRegistry();
    auto g = compileText(R"({"kestrel": 1, "passes": [
        {"name": "ramp", "type": "Ramp"},
        {"name": "p", "type": "Guided", "params": {"key": 1}},
        {"name": "q", "type": "Guided", "params": {"key": 1, "fail": true}},
        {"name": "sum", "type": "Sum"}],
      "edges": [{"from": "ramp.out", "to": ["p.in", "q.in", "p.guide", "q.guide"]},
        {"from": "p.out", "to": "sum.a"}, {"from": "q.out", "to": "sum.b"}],
      "outputs": ["sum.out"]})",
                         r);
    ASSERT_EQ(g->report().fused.size(), 1u);
    Parallel par(1);
    Executor ex(*g, par, {}, {4, 4});
    try {
        ex.runFrame(3);
        FAIL() << "the frame should fail";
    } catch (const FrameError& e) {
        EXPECT_EQ(std::string(e.what()),
                  "frame 3, pass 'p' (Guided, fused with 'q'): a fused pass fails");
    }
}

}  // namespace
}  // namespace kestrel::enginetest
