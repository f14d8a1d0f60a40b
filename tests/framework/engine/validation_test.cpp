// Every validation error the parser and compiler report: each points at its JSON path and says
// what was expected and what was found.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "TestPasses.h"

namespace kestrel::enginetest {
namespace {

std::string dump(const std::vector<Diagnostic>& diags) {
    std::string s;
    for (const auto& d : diags) s += "  [" + d.path + "] " + d.message + "\n";
    return s;
}

/// The diagnostics of a graph that must fail to parse or compile.
std::vector<Diagnostic> errorsOf(const std::string& json) {
    Registry r = testRegistry();
    try {
        compileText(json, r);
    } catch (const GraphError& e) {
        return e.diagnostics();
    }
    ADD_FAILURE() << "graph was accepted:\n" << json;
    return {};
}

/// Whether a diagnostic at exactly `path` mentions every fragment.
::testing::AssertionResult hasDiag(const std::vector<Diagnostic>& diags, const std::string& path,
                                   const std::vector<std::string>& fragments) {
    for (const auto& d : diags) {
        if (d.path != path) continue;
        bool all = true;
        for (const auto& f : fragments) all = all && d.message.find(f) != std::string::npos;
        if (all) return ::testing::AssertionSuccess();
    }
    return ::testing::AssertionFailure() << "no diagnostic at '" << path << "' with the expected "
                                         << "text among:\n"
                                         << dump(diags);
}

// A graph using the same passes correctly compiles: the errors below come from the defect
// each one plants, not from the scaffolding.
TEST(Validation, CorrectGraphCompiles) {
    Registry r = testRegistry();
    auto g = compileText(R"({"kestrel": 1, "name": "ok",
        "passes": [{"name": "src", "type": "Const"},
                   {"name": "a", "type": "AddOne", "params": {"alpha": 1, "count": 10,
                                                              "enabled": false, "mode": "gauss"}},
                   {"name": "n", "type": "Counter"}],
        "edges": [{"from": "src.out", "to": "a.in"},
                  {"from": "n.out", "to": "n.prev", "history": true}],
        "outputs": ["a.out", "n.out"]})",
                         r);
    EXPECT_EQ(g->executionOrder(), (std::vector<std::string>{"src", "a", "n"}));
}

TEST(Validation, SyntaxErrorReportsLineAndColumn) {
    // Line 3 has a trailing comma; the '}' that follows it is at column 30.
    const std::string text =
        "{\n"
        "  \"kestrel\": 1,\n"
        "  \"passes\": [ { \"name\": \"a\", } ]\n"
        "}\n";
    try {
        parseGraph(text, "graphs/broken.json");
        FAIL() << "syntax error accepted";
    } catch (const GraphError& e) {
        ASSERT_EQ(e.diagnostics().size(), 1u);
        const std::string& m = e.diagnostics()[0].message;
        EXPECT_EQ(m.rfind("graphs/broken.json:3:30: JSON syntax error", 0), 0u) << m;
    }
}

TEST(Validation, UnknownPassTypeSuggestsNearest) {
    auto d = errorsOf(R"({"kestrel": 1, "passes": [{"name": "src", "type": "Const"},
        {"name": "a", "type": "AddOen"}], "edges": [{"from": "src.out", "to": "a.in"}]})");
    EXPECT_TRUE(
        hasDiag(d, "passes[1].type", {"unknown pass type 'AddOen'", "did you mean 'AddOne'"}));
}

TEST(Validation, UnknownPassTypeFarFromEveryNameGetsNoSuggestion) {
    auto d = errorsOf(R"({"kestrel": 1, "passes": [{"name": "x", "type": "Zzzzzzzzzzzz"}]})");
    ASSERT_TRUE(hasDiag(d, "passes[0].type", {"unknown pass type 'Zzzzzzzzzzzz'"}));
    EXPECT_EQ(d[0].message.find("did you mean"), std::string::npos) << d[0].message;
}

TEST(Validation, UnknownPortsOnBothEndsOfAnEdge) {
    auto d = errorsOf(R"({"kestrel": 1, "passes": [{"name": "src", "type": "Const"},
        {"name": "a", "type": "AddOne"}],
        "edges": [{"from": "src.outt", "to": "a.in"}, {"from": "src.out", "to": "a.inn"}]})");
    EXPECT_TRUE(hasDiag(d, "edges[0].from", {"'src'", "no output 'outt'", "outputs: out"}));
    EXPECT_TRUE(hasDiag(d, "edges[1].to", {"'a'", "no input 'inn'", "inputs: in"}));
}

TEST(Validation, UnknownPassNamesInEdgesAndOutputs) {
    auto d = errorsOf(R"({"kestrel": 1, "passes": [{"name": "src", "type": "Const"},
        {"name": "a", "type": "AddOne"}],
        "edges": [{"from": "scr.out", "to": "a.in"}], "outputs": ["aa.out"]})");
    EXPECT_TRUE(hasDiag(d, "edges[0].from", {"unknown pass 'scr'", "did you mean 'src'"}));
    EXPECT_TRUE(hasDiag(d, "outputs[0]", {"unknown pass 'aa'", "did you mean 'a'"}));
}

TEST(Validation, FormatMismatch) {
    auto d = errorsOf(R"({"kestrel": 1, "passes": [{"name": "c", "type": "Color"},
        {"name": "a", "type": "AddOne"}], "edges": [{"from": "c.color", "to": "a.in"}]})");
    EXPECT_TRUE(
        hasDiag(d, "edges[0]", {"format mismatch", "c.color is float3", "a.in expects float"}));
}

TEST(Validation, TwoEdgesIntoOneInput) {
    auto d = errorsOf(R"({"kestrel": 1, "passes": [{"name": "s1", "type": "Const"},
        {"name": "s2", "type": "Const"}, {"name": "a", "type": "AddOne"}],
        "edges": [{"from": "s1.out", "to": "a.in"}, {"from": "s2.out", "to": "a.in"}]})");
    EXPECT_TRUE(hasDiag(d, "edges[1].to", {"a.in", "already fed by edges[0]"}));
}

TEST(Validation, MissingRequiredInput) {
    auto d = errorsOf(R"({"kestrel": 1, "passes": [{"name": "src", "type": "Const"},
        {"name": "sum", "type": "Sum"}], "edges": [{"from": "src.out", "to": "sum.a"}]})");
    EXPECT_TRUE(hasDiag(d, "passes[1]", {"required input 'b'", "'sum'", "not connected"}));
}

TEST(Validation, CycleWithoutHistoryEdgeNamesItsPasses) {
    auto d = errorsOf(R"({"kestrel": 1, "passes": [{"name": "src", "type": "Const"},
        {"name": "a", "type": "Sum"}, {"name": "b", "type": "AddOne"}, {"name": "c", "type": "AddOne"}],
        "edges": [{"from": "src.out", "to": "a.a"}, {"from": "c.out", "to": "a.b"},
                  {"from": "a.out", "to": "b.in"}, {"from": "b.out", "to": "c.in"}]})");
    ASSERT_TRUE(hasDiag(d, "edges", {"cycle without a history edge", "\"history\": true"}));
    // The cycle is named in edge direction (any rotation) and leaves out src, which feeds it.
    EXPECT_TRUE(hasDiag(d, "edges", {"a -> b", "b -> c", "c -> a"}));
    EXPECT_EQ(d[0].message.find("src"), std::string::npos) << d[0].message;
}

TEST(Validation, HistoryEdgeBreaksTheCycle) {
    Registry r = testRegistry();
    auto g = compileText(R"({"kestrel": 1, "passes": [{"name": "p", "type": "Previous"},
        {"name": "b", "type": "AddOne"}],
        "edges": [{"from": "p.out", "to": "b.in"}, {"from": "b.out", "to": "p.prev", "history": true}],
        "outputs": ["b.out"]})",
                         r);
    EXPECT_EQ(g->executionOrder(), (std::vector<std::string>{"p", "b"}));
}

TEST(Validation, ParameterTypeAndRange) {
    auto d = errorsOf(R"({"kestrel": 1, "passes": [
        {"name": "src", "type": "Const"},
        {"name": "a", "type": "AddOne", "params": {"alpha": "high", "count": 2.5}},
        {"name": "b", "type": "AddOne", "params": {"enabled": 1, "mode": "fast", "count": 11}},
        {"name": "c", "type": "AddOne", "params": {"alpha": 1.5}}],
        "edges": [{"from": "src.out", "to": "a.in"}, {"from": "a.out", "to": "b.in"},
                  {"from": "b.out", "to": "c.in"}]})");
    // The exact wording docs/design.md section 3 promises, with the parameter by name.
    bool exact = false;
    for (const auto& x : d)
        exact = exact ||
                x.str() == "passes[3].params.alpha (c.alpha): expected number in [0, 1], got 1.5";
    EXPECT_TRUE(exact) << dump(d);
    EXPECT_TRUE(hasDiag(d, "passes[1].params.alpha", {"expected number", "got \"high\""}));
    EXPECT_TRUE(hasDiag(d, "passes[1].params.count", {"expected integer in [1, 10]", "got 2.5"}));
    EXPECT_TRUE(hasDiag(d, "passes[2].params.count", {"expected integer in [1, 10]", "got 11"}));
    EXPECT_TRUE(hasDiag(d, "passes[2].params.enabled", {"expected bool", "got 1"}));
    EXPECT_TRUE(hasDiag(d, "passes[2].params.mode", {"box|gauss", "got \"fast\""}));
    EXPECT_EQ(d.size(), 6u) << dump(d);
}

// A choice spelled as a JSON scalar is that choice (--set 'input.antiAliased=true' parses the
// value as the boolean); a scalar that is no choice is still an error.
TEST(Validation, EnumChoiceSpelledAsAScalar) {
    Registry r = testRegistry();
    EXPECT_NO_THROW(compileText(R"({"kestrel": 1, "name": "ok",
        "passes": [{"name": "src", "type": "Const"},
                   {"name": "a", "type": "AddOne", "params": {"tristate": true}}],
        "edges": [{"from": "src.out", "to": "a.in"}], "outputs": ["a.out"]})",
                                r));
    auto d = errorsOf(R"({"kestrel": 1, "passes": [
        {"name": "src", "type": "Const"},
        {"name": "a", "type": "AddOne", "params": {"mode": true, "tristate": 1}}],
        "edges": [{"from": "src.out", "to": "a.in"}]})");
    EXPECT_TRUE(hasDiag(d, "passes[1].params.mode", {"box|gauss", "got true"})) << dump(d);
    EXPECT_TRUE(hasDiag(d, "passes[1].params.tristate", {"auto|true|false", "got 1"})) << dump(d);
}

TEST(Validation, UnknownParameterSuggestsNearest) {
    auto d = errorsOf(
        R"({"kestrel": 1, "passes": [{"name": "src", "type": "Const", "params": {"valeu": 2}}]})");
    EXPECT_TRUE(hasDiag(d, "passes[0].params.valeu",
                        {"unknown parameter 'valeu'", "Const", "did you mean 'value'"}));
}

TEST(Validation, DuplicatePassName) {
    auto d = errorsOf(R"({"kestrel": 1, "passes": [{"name": "a", "type": "Const"},
        {"name": "a", "type": "Const"}]})");
    EXPECT_TRUE(hasDiag(d, "passes[1].name", {"duplicate pass name 'a'"}));
}

TEST(Validation, MissingOrUnsupportedFormatVersion) {
    auto missing = errorsOf(R"({"passes": [{"name": "a", "type": "Const"}]})");
    EXPECT_TRUE(hasDiag(missing, "kestrel", {"missing graph format version", "\"kestrel\": 1"}));
    auto future = errorsOf(R"({"kestrel": 2, "passes": [{"name": "a", "type": "Const"}]})");
    EXPECT_TRUE(hasDiag(future, "kestrel", {"unsupported graph format version 2", "version 1"}));
    auto text = errorsOf(R"({"kestrel": "1", "passes": [{"name": "a", "type": "Const"}]})");
    EXPECT_TRUE(hasDiag(text, "kestrel", {"unsupported graph format version \"1\""}));
}

TEST(Validation, HistoryFlagMustMatchTheInput) {
    auto intoPlain = errorsOf(R"({"kestrel": 1, "passes": [{"name": "src", "type": "Const"},
        {"name": "a", "type": "AddOne"}], "edges": [{"from": "src.out", "to": "a.in", "history": true}]})");
    EXPECT_TRUE(hasDiag(intoPlain, "edges[0].history", {"a.in is not a history input"}));
    auto intoHistory = errorsOf(R"({"kestrel": 1, "passes": [{"name": "src", "type": "Const"},
        {"name": "n", "type": "Counter"}], "edges": [{"from": "src.out", "to": "n.prev"}]})");
    EXPECT_TRUE(
        hasDiag(intoHistory, "edges[0]", {"n.prev is a history input", "\"history\": true"}));
}

TEST(Validation, ErrorsAreGatheredIntoOneGraphError) {
    auto d = errorsOf(R"({"kestrel": 1, "passes": [
        {"name": "src", "type": "Const", "params": {"value": "x"}},
        {"name": "a", "type": "AddOen"},
        {"name": "b", "type": "AddOne", "params": {"alhpa": 0.1}},
        {"name": "s", "type": "Sum"}],
        "edges": [{"from": "src.out", "to": "b.in"}, {"from": "src.nope", "to": "s.a"}]})");
    EXPECT_TRUE(hasDiag(d, "passes[0].params.value", {"expected number"}));
    EXPECT_TRUE(hasDiag(d, "passes[1].type", {"AddOen"}));
    EXPECT_TRUE(hasDiag(d, "passes[2].params.alhpa", {"did you mean 'alpha'"}));
    EXPECT_TRUE(hasDiag(d, "edges[1].from", {"no output 'nope'"}));
    EXPECT_TRUE(hasDiag(d, "passes[3]", {"required input 'a'"}));
    EXPECT_TRUE(hasDiag(d, "passes[3]", {"required input 'b'"}));
    EXPECT_EQ(d.size(), 6u) << dump(d);

    // The exception's own message leads with the first finding and counts the rest.
    Registry r = testRegistry();
    try {
        compileText(R"({"kestrel": 1, "passes": [{"name": "a", "type": "AddOen"},
            {"name": "b", "type": "Constt"}]})",
                    r);
        FAIL() << "accepted";
    } catch (const GraphError& e) {
        EXPECT_STREQ(
            e.what(),
            "passes[0].type (a): unknown pass type 'AddOen' (did you mean 'AddOne'?) (and 1 more)");
    }
}

TEST(Validation, StructuralErrorsInTheDocumentAreGathered) {
    auto d = errorsOf(R"({"kestrel": 1, "nmae": "x",
        "passes": [{"name": "a", "type": "Const", "colour": 1}, {"type": "Const"}],
        "edges": [{"from": "a", "to": "b.in"}], "outputs": [3]})");
    EXPECT_TRUE(hasDiag(d, "nmae", {"unknown key 'nmae'"}));
    EXPECT_TRUE(hasDiag(d, "passes[0].colour", {"unknown key 'colour'"}));
    EXPECT_TRUE(hasDiag(d, "passes[1].name", {"non-empty string"}));
    EXPECT_TRUE(hasDiag(d, "edges[0].from", {"\"pass.port\"", "got \"a\""}));
    EXPECT_TRUE(hasDiag(d, "outputs[0]", {"\"pass.port\""}));
}

}  // namespace
}  // namespace kestrel::enginetest

namespace kestrel::enginetest {
namespace {

TEST(Overrides, PatternSetsEveryMatchingPassAndNothingElse) {
    GraphDesc g;
    g.passes = {{"diffuse_atrous0", "ATrous", "{}", ""},
                {"diffuse_atrous1", "ATrous", "{}", ""},
                {"taa", "TAA", "{}", ""}};
    applyOverride(g, "*atrous*.exact=true");
    EXPECT_EQ(g.passes[0].paramsJson, R"({"exact":true})");
    EXPECT_EQ(g.passes[1].paramsJson, R"({"exact":true})");
    EXPECT_EQ(g.passes[2].paramsJson, "{}");
    applyOverride(g, "taa.alpha=0.2");
    EXPECT_EQ(g.passes[2].paramsJson, R"({"alpha":0.2})");
    try {
        applyOverride(g, "*variance*.exact=true");
        FAIL() << "a pattern matching nothing must be an error";
    } catch (const Error& e) {
        EXPECT_NE(std::string(e.what()).find("no pass matches '*variance*'"), std::string::npos)
            << e.what();
    }
}

}  // namespace
}  // namespace kestrel::enginetest
