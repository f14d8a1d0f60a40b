// Lifetime-based aliasing: transient memory is reused once its last reader has run, never
// under a pass's own input, never under a resource still to be read; an output declared in
// place of an input takes over that input's memory only when its pass is the input's last
// reader.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "PlanChecks.h"
#include "TestPasses.h"

namespace kestrel::enginetest {
namespace {

/// `count` NeighbourAverage passes after a Ramp source; the last one is the graph output.
std::string chainGraph(int count) {
    std::string passes = R"({"name": "p0", "type": "Ramp"})";
    std::string edges;
    for (int i = 1; i <= count; ++i) {
        std::string n = "p" + std::to_string(i), prev = "p" + std::to_string(i - 1);
        passes += R"(, {"name": ")" + n + R"(", "type": "NeighbourAverage"})";
        edges += std::string(i > 1 ? ", " : "") + R"({"from": ")" + prev + R"(.out", "to": ")" + n +
                 R"(.in"})";
    }
    return R"({"kestrel": 1, "passes": [)" + passes + R"(], "edges": [)" + edges +
           R"(], "outputs": ["p)" + std::to_string(count) + R"(.out"]})";
}

TEST(Memory, ChainOfFiftyPassesUsesTwoPlanes) {
    Registry r = testRegistry();
    auto g = compileText(chainGraph(49), r);  // 50 passes, 50 float resources
    ASSERT_EQ(g->executionOrder().size(), 50u);
    EXPECT_EQ(g->unaliasedPlaneCount(), 50);
    // Ping-pong: each pass needs its input and its output alive, nothing more.
    EXPECT_EQ(g->transientPlaneCount(), 2);

    const Extent ext{9, 3};
    Parallel par(1);
    Executor ex(*g, par, {}, ext);
    ex.runFrame(1);
    EXPECT_EQ(ex.memory().transientPlanes, 2u);
    EXPECT_EQ(ex.memory().historyPlanes, 0u);
    EXPECT_EQ(ex.memory().bytes, 2 * ext.pixels() * sizeof(float));

    // Same arithmetic without the engine: 49 out-of-place neighbour averages of the ramp.
    // In-place execution (output aliasing input) would mix already-averaged values in.
    std::vector<float> ref(ext.pixels()), tmp(ext.pixels());
    for (int y = 0; y < ext.height; ++y)
        for (int x = 0; x < ext.width; ++x) ref[size_t(y * ext.width + x)] = float(x + 10 * y);
    for (int k = 0; k < 49; ++k) {
        for (int y = 0; y < ext.height; ++y) {
            const float* s = &ref[size_t(y * ext.width)];
            float* d = &tmp[size_t(y * ext.width)];
            d[0] = s[0];
            for (int x = 1; x < ext.width; ++x) d[x] = 0.5f * (s[x] + s[x - 1]);
        }
        std::swap(ref, tmp);
    }
    ImageView out = ex.output("p49.out");
    for (int y = 0; y < ext.height; ++y)
        for (int x = 0; x < ext.width; ++x)
            ASSERT_EQ(out.at(0, x, y), ref[size_t(y * ext.width + x)]) << x << "," << y;
}

TEST(Memory, NoResourceSharesPlanesWithAnotherAliveAtTheSameTime) {
    Registry r = testRegistry();
    auto g = compileText(chainGraph(49), r);
    const auto& res = g->resources();
    for (size_t i = 0; i < res.size(); ++i)
        for (size_t j = i + 1; j < res.size(); ++j) {
            // Lifetimes [firstUse, lastUse] that overlap must not share a plane.
            bool overlap = res[i].firstUse <= res[j].lastUse && res[j].firstUse <= res[i].lastUse;
            if (!overlap) continue;
            for (int a : res[i].planes)
                for (int b : res[j].planes)
                    EXPECT_NE(a, b) << res[i].producer << " and " << res[j].producer;
        }
}

TEST(Memory, ResourceIsKeptUntilItsLastReader) {
    Registry r = testRegistry();
    // ramp is read by `avg` (early) and by `sum` (last): b and avg must not land on its plane.
    auto g = compileText(R"({"kestrel": 1, "passes": [{"name": "ramp", "type": "Ramp"},
        {"name": "b", "type": "AddOne"}, {"name": "avg", "type": "NeighbourAverage"},
        {"name": "c", "type": "AddOne"}, {"name": "sum", "type": "Sum"}],
        "edges": [{"from": "ramp.out", "to": "b.in"}, {"from": "b.out", "to": "avg.in"},
                  {"from": "avg.out", "to": "c.in"}, {"from": "c.out", "to": "sum.a"},
                  {"from": "ramp.out", "to": "sum.b"}],
        "outputs": ["sum.out"]})",
                         r);
    EXPECT_EQ(g->unaliasedPlaneCount(), 5);
    EXPECT_EQ(g->transientPlaneCount(), 3);
    Parallel par(1);
    Executor ex(*g, par, {}, Extent{4, 2});
    ex.runFrame(1);
    ImageView out = ex.output("sum.out");
    for (int y = 0; y < 2; ++y)
        for (int x = 0; x < 4; ++x) {
            float ramp = float(x + 10 * y), left = float(x > 0 ? x - 1 + 10 * y : 10 * y);
            float expected = (0.5f * ((ramp + 1.f) + (left + 1.f)) + 1.f) + ramp;
            EXPECT_EQ(out.at(0, x, y), expected) << x << "," << y;
        }
}

std::string scaleChain(int count, bool alsoRead);

// The graph of ResourceIsKeptUntilItsLastReader with `mid` (a pass type) between avg and c.
std::string keptGraph(const std::string& mid) {
    return R"({"kestrel": 1, "passes": [{"name": "ramp", "type": "Ramp"},
        {"name": "b", "type": "AddOne"}, {"name": "avg", "type": "NeighbourAverage"},
        {"name": "mid", "type": ")" +
           mid + R"("}, {"name": "c", "type": "AddOne"}, {"name": "sum", "type": "Sum"}],
        "edges": [{"from": "ramp.out", "to": "b.in"}, {"from": "b.out", "to": "avg.in"},
                  {"from": "avg.out", "to": "mid.in"}, {"from": "mid.out", "to": "c.in"},
                  {"from": "c.out", "to": "sum.a"}, {"from": "ramp.out", "to": "sum.b"}],
        "outputs": ["sum.out"]})";
}

TEST(Memory, IdlePlanesAreExactlyThoseNoLiveResourceHolds) {
    Registry r = testRegistry();
    for (const std::string& json : {keptGraph("AddOne"), chainGraph(6), scaleChain(4, true)}) {
        auto g = compileText(json, r);
        const size_t steps = g->executionOrder().size();
        for (size_t k = 0; k < steps; ++k) {
            std::vector<int> holder(size_t(g->transientPlaneCount()), 0);
            for (const auto& res : g->resources())
                if (!res.history && res.firstUse <= int(k) && int(k) <= res.lastUse)
                    for (int pl : res.planes) holder[size_t(pl)] = 1;
            for (int pl : g->idlePlanes(k)) {
                EXPECT_EQ(holder[size_t(pl)], 0) << json << "\nstep " << k << ": plane " << pl;
                holder[size_t(pl)] = 2;
            }
            for (size_t pl = 0; pl < holder.size(); ++pl)
                EXPECT_NE(holder[pl], 0)
                    << json << "\nstep " << k << ": plane " << pl << " neither held nor idle";
        }
    }
}

TEST(Memory, APassMayOverwriteItsIdlePlanes) {
    Registry r = testRegistry();
    // Four planes while `both` runs (ramp, b, c, both.out); b and c are dead after it, so one
    // plane is idle while `mid` runs (ramp, both.out and mid.out held).
    auto g = compileText(R"({"kestrel": 1, "passes": [{"name": "ramp", "type": "Ramp"},
        {"name": "b", "type": "AddOne"}, {"name": "c", "type": "AddOne"},
        {"name": "both", "type": "Sum"}, {"name": "mid", "type": "ScribbleIdle"},
        {"name": "sum", "type": "Sum"}],
        "edges": [{"from": "ramp.out", "to": ["b.in", "c.in", "sum.b"]},
                  {"from": "b.out", "to": "both.a"}, {"from": "c.out", "to": "both.b"},
                  {"from": "both.out", "to": "mid.in"}, {"from": "mid.out", "to": "sum.a"}],
        "outputs": ["sum.out"]})",
                         r);
    EXPECT_EQ(g->transientPlaneCount(), 4);
    Parallel par(1);
    Executor ex(*g, par, {}, Extent{4, 2});
    for (int frame = 1; frame <= 2; ++frame) {
        ScribbleIdlePass::lastIdleCount = 0;
        ex.runFrame(frame);
        EXPECT_EQ(ScribbleIdlePass::lastIdleCount, 1u);
        ImageView out = ex.output("sum.out");
        for (int y = 0; y < 2; ++y)
            for (int x = 0; x < 4; ++x) {
                const float ramp = float(x + 10 * y);
                EXPECT_EQ(out.at(0, x, y), (2.f * (ramp + 1.f) + 1.f) + ramp) << x << "," << y;
            }
    }
}

TEST(Memory, MultiChannelResourcesGetDistinctPlanesPerChannel) {
    Registry r = testRegistry();
    auto g = compileText(R"({"kestrel": 1, "passes": [{"name": "c", "type": "Color"}],
        "outputs": ["c.color"]})",
                         r);
    ASSERT_EQ(g->resources().size(), 1u);
    EXPECT_EQ(g->resources()[0].planes, (std::vector<int>{0, 1, 2}));
    Parallel par(1);
    Executor ex(*g, par, {}, Extent{2, 2});
    ex.runFrame(1);
    ImageView v = ex.output("c.color");
    for (int ch = 0; ch < 3; ++ch) EXPECT_EQ(v.at(ch, 1, 1), float(ch));
}

/// A Ramp source, then `count` ScaleInPlace passes in a chain; `alsoRead`: the ramp is also
/// read by a Sum at the end (so the first pass is not its last reader).
std::string scaleChain(int count, bool alsoRead) {
    std::string passes = R"({"name": "ramp", "type": "Ramp"})", edges;
    std::string prev = "ramp";
    for (int i = 1; i <= count; ++i) {
        const std::string n = "s" + std::to_string(i);
        passes += R"(, {"name": ")" + n + R"(", "type": "ScaleInPlace"})";
        edges += std::string(i > 1 ? ", " : "") + R"({"from": ")" + prev + R"(.out", "to": ")" + n +
                 R"(.in"})";
        prev = n;
    }
    std::string out = prev + ".out";
    if (alsoRead) {
        passes += R"(, {"name": "sum", "type": "Sum"})";
        edges += R"(, {"from": ")" + prev +
                 R"(.out", "to": "sum.a"}, {"from": "ramp.out", "to": "sum.b"})";
        out = "sum.out";
    }
    return R"({"kestrel": 1, "passes": [)" + passes + R"(], "edges": [)" + edges +
           R"(], "outputs": [")" + out + R"("]})";
}

float scaled(float v, int times) {
    for (int k = 0; k < times; ++k) v = 2.f * v + 1.f;
    return v;
}

TEST(Memory, InPlaceOutputsShareTheirInputsPlanes) {
    Registry r = testRegistry();
    auto g = compileText(scaleChain(10, false), r);
    EXPECT_EQ(g->unaliasedPlaneCount(), 11);
    EXPECT_EQ(g->transientPlaneCount(), 1);  // every pass writes over its input
    int inPlace = 0;
    for (const auto& res : g->resources()) inPlace += res.inPlaceOf >= 0;
    EXPECT_EQ(inPlace, 10);
    Parallel par(2);
    const Extent ext{7, 3};
    Executor ex(*g, par, {}, ext);
    ex.runFrame(1);
    EXPECT_TRUE(ScaleInPlacePass::lastRunInPlace);
    ImageView out = ex.output("s10.out");
    for (int y = 0; y < ext.height; ++y)
        for (int x = 0; x < ext.width; ++x)
            ASSERT_EQ(out.at(0, x, y), scaled(float(x + 10 * y), 10)) << x << "," << y;
}

TEST(Memory, NoInPlaceWhenTheInputIsReadLater) {
    Registry r = testRegistry();
    // The ramp is read again by `sum` after s1: s1 must not write over it.
    auto g = compileText(scaleChain(3, true), r);
    for (const auto& res : g->resources())
        if (res.producer == "s1.out") {
            EXPECT_EQ(res.inPlaceOf, -1);
        }
    Parallel par(1);
    Executor ex(*g, par, {}, Extent{5, 2});
    ex.runFrame(1);
    ImageView out = ex.output("sum.out");
    for (int y = 0; y < 2; ++y)
        for (int x = 0; x < 5; ++x) {
            const float ramp = float(x + 10 * y);
            ASSERT_EQ(out.at(0, x, y), scaled(ramp, 3) + ramp) << x << "," << y;
        }
}

TEST(Memory, NoInPlaceWhenTheInputFeedsTwoPortsOfThePass) {
    Registry r = testRegistry();
    auto g = compileText(R"({"kestrel": 1, "passes": [{"name": "ramp", "type": "Ramp"},
        {"name": "s", "type": "ScaleInPlace"}],
        "edges": [{"from": "ramp.out", "to": "s.in"}, {"from": "ramp.out", "to": "s.other"}],
        "outputs": ["s.out"]})",
                         r);
    EXPECT_EQ(g->transientPlaneCount(), 2);
    Parallel par(1);
    Executor ex(*g, par, {}, Extent{4, 2});
    ex.runFrame(1);
    EXPECT_FALSE(ScaleInPlacePass::lastRunInPlace);
    for (int x = 0; x < 4; ++x)
        EXPECT_EQ(ex.output("s.out").at(0, x, 1), 3.f * float(x + 10) + 1.f);
}

TEST(Memory, NoInPlaceOverAGraphOutputOrAHistoryResource) {
    Registry r = testRegistry();
    // ramp.out is kept to the end of the frame (a graph output): s must not write over it.
    auto marked = compileText(R"({"kestrel": 1, "passes": [{"name": "ramp", "type": "Ramp"},
        {"name": "s", "type": "ScaleInPlace"}],
        "edges": [{"from": "ramp.out", "to": "s.in"}],
        "outputs": ["s.out", "ramp.out"]})",
                              r);
    for (const auto& res : marked->resources()) EXPECT_EQ(res.inPlaceOf, -1) << res.producer;
    Parallel par(1);
    Executor ex(*marked, par, {}, Extent{3, 2});
    ex.runFrame(1);
    for (int x = 0; x < 3; ++x) {
        EXPECT_EQ(ex.output("ramp.out").at(0, x, 1), float(x + 10));
        EXPECT_EQ(ex.output("s.out").at(0, x, 1), 2.f * float(x + 10) + 1.f);
    }
    // ramp.out is read next frame through a history edge: it persists, so it is never aliased.
    auto history = compileText(R"({"kestrel": 1, "passes": [{"name": "ramp", "type": "Ramp"},
        {"name": "s", "type": "ScaleInPlace"}, {"name": "p", "type": "Previous"},
        {"name": "sum", "type": "Sum"}],
        "edges": [{"from": "ramp.out", "to": "s.in"},
                  {"from": "ramp.out", "to": "p.prev", "history": true},
                  {"from": "s.out", "to": "sum.a"}, {"from": "p.out", "to": "sum.b"}],
        "outputs": ["sum.out"]})",
                               r);
    for (const auto& res : history->resources()) EXPECT_EQ(res.inPlaceOf, -1) << res.producer;
    Executor hx(*history, par, {}, Extent{3, 2});
    hx.runFrame(1);
    hx.runFrame(2);
    for (int x = 0; x < 3; ++x)  // 2 ramp + 1 and last frame's ramp, intact
        EXPECT_EQ(hx.output("sum.out").at(0, x, 1), 3.f * float(x + 10) + 1.f);
}

/// The history resource whose idle planes hold `producer`'s resource ("" if none).
std::string historyHolding(const CompiledGraph& g, const std::string& producer) {
    for (const auto& res : g.resources())
        if (res.producer == producer && !res.historyPlanes.empty())
            return g.resources()[size_t(res.historyPlanes[0].resource)].producer;
    return "";
}

std::unique_ptr<CompiledGraph> compileWith(const std::string& json, const Registry& r,
                                           bool historyIdle) {
    CompileOptions o;
    o.historyIdle = historyIdle;
    return compileGraph(parseGraph(json), r, o);
}

// ramp.out is double-buffered (read as last frame's value after this frame's is written): once
// `p` has read last frame's, that buffer is idle to the end of the frame and holds a.out.
TEST(Memory, TransientLivesInLastFramesBufferAfterItsLastRead) {
    Registry r = testRegistry();
    const std::string json = R"({"kestrel": 1, "passes": [{"name": "ramp", "type": "Ramp"},
        {"name": "p", "type": "Previous"}, {"name": "a", "type": "AddOne"},
        {"name": "sum", "type": "Sum"}],
        "edges": [{"from": "ramp.out", "to": "p.prev", "history": true},
                  {"from": "p.out", "to": "a.in"},
                  {"from": "a.out", "to": "sum.a"}, {"from": "p.out", "to": "sum.b"}],
        "outputs": ["sum.out"]})";
    auto lent = compileWith(json, r, true), own = compileWith(json, r, false);
    testutil::expectHistoryLentOnlyWhileIdle(*lent);
    EXPECT_EQ(historyHolding(*lent, "a.out"), "ramp.out");
    EXPECT_EQ(lent->transientPlaneCount(), 2);  // p.out and sum.out
    EXPECT_EQ(own->transientPlaneCount(), 3);
    Parallel par(2);
    Executor ex(*lent, par, {}, Extent{5, 3}), ox(*own, par, {}, Extent{5, 3});
    for (int frame = 1; frame <= 4; ++frame) {
        ex.runFrame(frame);
        ox.runFrame(frame);
        for (int y = 0; y < 3; ++y)
            for (int x = 0; x < 5; ++x) {
                // Last frame's ramp intact: writing a.out into this frame's buffer would
                // show here a frame later.
                const float prev = frame == 1 ? -1.f : float(x + 10 * y);
                ASSERT_EQ(ex.output("sum.out").at(0, x, y), 2.f * prev + 1.f) << frame;
                ASSERT_EQ(ox.output("sum.out").at(0, x, y), 2.f * prev + 1.f) << frame;
            }
    }
}

// s.out is single-buffered (last frame's value read by `p` before `s` writes this frame's) and
// written in place of a.out, its input: a.out lives in s.out's planes from its first step.
TEST(Memory, TransientLivesInTheHistoryWrittenInPlaceOfIt) {
    Registry r = testRegistry();
    const std::string json = R"({"kestrel": 1, "passes": [{"name": "p", "type": "Previous"},
        {"name": "a", "type": "AddOne"}, {"name": "s", "type": "ScaleInPlace"}],
        "edges": [{"from": "s.out", "to": "p.prev", "history": true},
                  {"from": "p.out", "to": "a.in"}, {"from": "a.out", "to": "s.in"}],
        "outputs": ["s.out"]})";
    auto lent = compileWith(json, r, true), own = compileWith(json, r, false);
    testutil::expectHistoryLentOnlyWhileIdle(*lent);
    EXPECT_EQ(historyHolding(*lent, "a.out"), "s.out");
    EXPECT_EQ(lent->transientPlaneCount(), 1);  // p.out
    EXPECT_EQ(own->transientPlaneCount(), 2);
    Parallel par(1);
    Executor ex(*lent, par, {}, Extent{4, 2});
    float expected = 1.f;  // s = 2 (p + 1) + 1, p = last frame's s (-1 on the first frame)
    for (int frame = 1; frame <= 4; ++frame) {
        ex.runFrame(frame);
        EXPECT_TRUE(ScaleInPlacePass::lastRunInPlace);
        for (int x = 0; x < 4; ++x) ASSERT_EQ(ex.output("s.out").at(0, x, 1), expected) << frame;
        expected = 2.f * (expected + 1.f) + 1.f;
    }
}

// n.out's one buffer is idle from p's read until n writes it, but n reads a.out while writing:
// without an in-place declaration (NeighbourAverage reads its left neighbour) a.out must not be
// placed in n.out's planes (NeighbourAverage throws on aliased input and output).
TEST(Memory, HistoryIsNotLentToItsWritersInputUnlessWrittenInPlace) {
    Registry r = testRegistry();
    const std::string json = R"({"kestrel": 1, "passes": [{"name": "p", "type": "Previous"},
        {"name": "a", "type": "AddOne"}, {"name": "n", "type": "NeighbourAverage"}],
        "edges": [{"from": "n.out", "to": "p.prev", "history": true},
                  {"from": "p.out", "to": "a.in"}, {"from": "a.out", "to": "n.in"}],
        "outputs": ["n.out"]})";
    auto g = compileWith(json, r, true);
    testutil::expectHistoryLentOnlyWhileIdle(*g);
    EXPECT_EQ(historyHolding(*g, "a.out"), "");
    Parallel par(1);
    Executor ex(*g, par, {}, Extent{3, 1});
    ex.runFrame(1);  // p = -1, a = 0, n = 0
    ex.runFrame(2);  // p = 0, a = 1, n = 1
    for (int x = 0; x < 3; ++x) EXPECT_EQ(ex.output("n.out").at(0, x, 0), 1.f);
}

TEST(Memory, InPlaceDeclarationsAreChecked) {
    // Only after an output, only of a this-frame input of the same format.
    EXPECT_THROW(PassDesc("T", "").input("a", Format::Float, "").inPlaceOf("a"), Error);
    EXPECT_THROW(PassDesc("T", "")
                     .input("a", Format::Float3, "")
                     .output("o", Format::Float, "")
                     .inPlaceOf("a"),
                 Error);
    EXPECT_THROW(PassDesc("T", "")
                     .historyInput("a", Format::Float, "")
                     .output("o", Format::Float, "")
                     .inPlaceOf("a"),
                 Error);
    EXPECT_THROW(PassDesc("T", "").output("o", Format::Float, "").inPlaceOf("missing"), Error);
    EXPECT_NO_THROW(PassDesc("T", "")
                        .input("a", Format::Float, "")
                        .output("o", Format::Float, "")
                        .inPlaceOf("a"));
}

}  // namespace
}  // namespace kestrel::enginetest
