// Pruning, absent inputs and forwarding: what the compiler leaves out, and why it says so.
#include <gtest/gtest.h>

#include <algorithm>
#include <string>
#include <vector>

#include "TestPasses.h"

namespace kestrel::enginetest {
namespace {

using Names = std::vector<std::string>;

std::string reasonOf(const std::vector<LeftOutPass>& list, const std::string& pass) {
    for (const auto& p : list)
        if (p.pass == pass) return p.reason;
    return "<not listed>";
}

float runOnce(CompiledGraph& g, const std::string& output) {
    Parallel par(1);
    Executor ex(g, par, {}, Extent{3, 2});
    ex.runFrame(1);
    return ex.output(output).at(0, 2, 1);
}

TEST(Pruning, PassContributingToNoOutputIsNotExecuted) {
    Registry r = testRegistry();
    // `dead` throws if executed; `deadTail` only consumes it.
    auto g = compileText(R"({"kestrel": 1, "passes": [{"name": "src", "type": "Const"},
        {"name": "dead", "type": "Explode"}, {"name": "a", "type": "AddOne"},
        {"name": "deadTail", "type": "AddOne"}],
        "edges": [{"from": "src.out", "to": "dead.in"}, {"from": "src.out", "to": "a.in"},
                  {"from": "dead.out", "to": "deadTail.in"}],
        "outputs": ["a.out"]})",
                         r);
    EXPECT_EQ(g->executionOrder(), (Names{"src", "a"}));
    EXPECT_EQ(reasonOf(g->report().pruned, "dead"), "contributes to no output");
    EXPECT_EQ(reasonOf(g->report().pruned, "deadTail"), "contributes to no output");
    EXPECT_EQ(g->report().pruned.size(), 2u);
    EXPECT_FLOAT_EQ(runOnce(*g, "a.out"), 2.f);
    // The DOT export shows pruned passes greyed out with their reason.
    EXPECT_NE(g->toDot().find("pruned: contributes to no output"), std::string::npos);
}

TEST(Pruning, AnInputThePassDeclaresUnusedIsDisconnectedAndItsProducerLeftOut) {
    Registry r = testRegistry();
    // `dead` throws if executed: it feeds only the input PreferFirst ignores.
    auto g = compileText(R"({"kestrel": 1, "passes": [{"name": "src", "type": "Const"},
        {"name": "dead", "type": "Explode"}, {"name": "pick", "type": "PreferFirst"}],
        "edges": [{"from": "src.out", "to": "dead.in"}, {"from": "src.out", "to": "pick.first"},
                  {"from": "dead.out", "to": "pick.second"}],
        "outputs": ["pick.out"]})",
                         r);
    EXPECT_EQ(g->executionOrder(), (Names{"src", "pick"}));
    EXPECT_EQ(reasonOf(g->report().pruned, "dead"), "contributes to no output");
    const auto& notes = g->report().notes;
    EXPECT_NE(
        std::find(notes.begin(), notes.end(), "pick: input 'second' not read: first is bound"),
        notes.end());
    EXPECT_FLOAT_EQ(runOnce(*g, "pick.out"), 1.f);
}

TEST(Pruning, SinkIsAlwaysLiveAndAPassMarkedWithoutPortToo) {
    Registry r = testRegistry();
    auto g = compileText(R"({"kestrel": 1, "passes": [{"name": "src", "type": "Const"},
        {"name": "w", "type": "Sink"}, {"name": "a", "type": "AddOne"}, {"name": "b", "type": "AddOne"}],
        "edges": [{"from": "src.out", "to": "w.in"}, {"from": "src.out", "to": "a.in"},
                  {"from": "src.out", "to": "b.in"}],
        "outputs": ["b"]})",
                         r);
    EXPECT_EQ(g->executionOrder(), (Names{"src", "w", "b"}));
    EXPECT_EQ(reasonOf(g->report().pruned, "a"), "contributes to no output");
    ASSERT_EQ(g->sinks().size(), 1u);
    EXPECT_EQ(g->sinks()[0].first, "w");
}

TEST(Pruning, PassWhoseRequiredInputIsAbsentIsLeftOutWithItsReason) {
    Registry r = testRegistry();
    // missing.out is absent, so `mid` has nothing to compute; `user` only reads it optionally
    // and adapts (writes 7 instead of 2 * opt).
    auto g = compileText(R"({"kestrel": 1, "passes": [{"name": "missing", "type": "Missing"},
        {"name": "mid", "type": "AddOne"}, {"name": "user", "type": "OptionalUser"}],
        "edges": [{"from": "missing.out", "to": "mid.in"}, {"from": "mid.out", "to": "user.opt"}],
        "outputs": ["user.out"]})",
                         r);
    EXPECT_EQ(g->executionOrder(), (Names{"user"}));
    std::string why = reasonOf(g->report().pruned, "mid");
    EXPECT_NE(why.find("input 'in' has no data"), std::string::npos) << why;
    EXPECT_NE(why.find("missing.out"), std::string::npos) << why;
    EXPECT_NE(why.find("scene has no albedo AOV"), std::string::npos) << why;
    EXPECT_NE(reasonOf(g->report().pruned, "missing"), "<not listed>");
    EXPECT_EQ(g->report().absent, (Names{"missing.out: scene has no albedo AOV"}));
    EXPECT_FLOAT_EQ(runOnce(*g, "user.out"), 7.f);
}

TEST(Pruning, SinkDependingOnAnAbsentChainFailsNamingTheChain) {
    Registry r = testRegistry();
    const char* graph = R"({"kestrel": 1, "passes": [{"name": "missing", "type": "Missing"},
        {"name": "mid", "type": "AddOne"}, {"name": "writer", "type": "Sink"}],
        "edges": [{"from": "missing.out", "to": "mid.in"}, {"from": "mid.out", "to": "writer.in"}]})";
    try {
        compileText(graph, r);
        FAIL() << "compiled a sink whose input cannot be produced";
    } catch (const GraphError& e) {
        FAIL() << "a scene problem is not a validation error: " << e.what();
    } catch (const Error& e) {
        std::string m = e.what();
        for (const char* part : {"'writer'", "'mid'", "missing.out", "scene has no albedo AOV"})
            EXPECT_NE(m.find(part), std::string::npos) << part << " not in: " << m;
    }
    // Validation alone (no scene) accepts the same graph.
    CompileOptions vo;
    vo.validateOnly = true;
    EXPECT_NO_THROW(compileGraph(parseGraph(graph), r, vo));
}

TEST(Pruning, MarkedOutputThatCannotBeProducedFails) {
    Registry r = testRegistry();
    try {
        compileText(R"({"kestrel": 1, "passes": [{"name": "missing", "type": "Missing"},
            {"name": "mid", "type": "AddOne"}],
            "edges": [{"from": "missing.out", "to": "mid.in"}], "outputs": ["mid.out"]})",
                    r);
        FAIL() << "compiled an output that cannot be produced";
    } catch (const Error& e) {
        std::string m = e.what();
        EXPECT_NE(m.find("mid.out"), std::string::npos) << m;
        EXPECT_NE(m.find("scene has no albedo AOV"), std::string::npos) << m;
    }
}

TEST(Pruning, ForwardingLeavesThePassOutAndConsumersReadUpstream) {
    Registry r = testRegistry();
    auto g = compileText(R"({"kestrel": 1, "passes": [{"name": "src", "type": "Const",
        "params": {"value": 3}}, {"name": "fwd", "type": "Forward"}, {"name": "a", "type": "AddOne"}],
        "edges": [{"from": "src.out", "to": "fwd.in"}, {"from": "fwd.out", "to": "a.in"}],
        "outputs": ["a.out"]})",
                         r);
    EXPECT_EQ(g->executionOrder(), (Names{"src", "a"}));
    EXPECT_EQ(reasonOf(g->report().elided, "fwd"), "nothing to do: out is in");
    EXPECT_TRUE(g->report().pruned.empty());
    // a reads src's resource directly: the only resource is src.out (+ the marked a.out).
    ASSERT_EQ(g->resources().size(), 2u);
    EXPECT_EQ(g->resources()[0].producer, "src.out");
    EXPECT_FLOAT_EQ(runOnce(*g, "a.out"), 4.f);
}

TEST(Pruning, MarkedForwardedOutputReadsTheUpstreamResource) {
    Registry r = testRegistry();
    auto g = compileText(R"({"kestrel": 1, "passes": [{"name": "src", "type": "Const",
        "params": {"value": 3}}, {"name": "f1", "type": "Forward"}, {"name": "f2", "type": "Forward"}],
        "edges": [{"from": "src.out", "to": "f1.in"}, {"from": "f1.out", "to": "f2.in"}],
        "outputs": ["f2.out"]})",
                         r);
    EXPECT_EQ(g->executionOrder(), (Names{"src"}));
    EXPECT_EQ(g->report().elided.size(), 2u);
    EXPECT_FLOAT_EQ(runOnce(*g, "f2.out"), 3.f);
}

}  // namespace
}  // namespace kestrel::enginetest
