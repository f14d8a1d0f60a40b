// Groups (docs/graphs.md): expansion into flat passes named by instance path, parameter binding,
// history edges through group inputs, include and extends, errors at the definition's JSON path
// naming the instance path, --set on instances, DOT clusters.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "TempDir.h"
#include "TestPasses.h"

namespace kestrel::enginetest {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

// A group "inc": in.x -> a (AddOne) -> b (AddOne) -> out.y, and a Counter fed back through a
// history edge; its parameter alpha drives both AddOne passes.
const char* kGroup = R"("groups": {
    "inc": {
      "inputs": ["x"], "outputs": ["y", "count"],
      "params": {"alpha": 0.25},
      "passes": [{"name": "a", "type": "AddOne", "params": {"alpha": "$alpha"}},
                 {"name": "b", "type": "AddOne", "params": {"alpha": "$alpha", "count": 3}},
                 {"name": "n", "type": "Counter"}],
      "edges": [{"from": "in.x", "to": "a.in"},
                {"from": "a.out", "to": "b.in"},
                {"from": "n.out", "to": "n.prev", "history": true},
                {"from": "b.out", "to": "out.y"},
                {"from": "n.out", "to": "out.count"}]}})";

std::string graphWith(const std::string& passes, const std::string& edges,
                      const std::string& outputs = "[]") {
    return std::string(R"({"kestrel": 1, "name": "g", )") + kGroup + R"(, "passes": )" + passes +
           R"(, "edges": )" + edges + R"(, "outputs": )" + outputs + "}";
}

const std::string kTwoInstances = graphWith(
    R"([{"name": "src", "type": "Const"},
        {"name": "p", "group": "inc"},
        {"name": "q", "group": "inc", "params": {"alpha": 0.75}}])",
    R"([{"from": "src.out", "to": ["p.x", "q.x"]}])", R"(["p.y", "q.y", "q.count"])");

const PassNode* findPass(const GraphDesc& g, const std::string& name) {
    for (const auto& p : g.passes)
        if (p.name == name) return &p;
    return nullptr;
}

json paramsOf(const GraphDesc& g, const std::string& name) {
    const PassNode* p = findPass(g, name);
    EXPECT_NE(p, nullptr) << name;
    return p ? json::parse(p->paramsJson) : json();
}

std::vector<std::string> edgeList(const GraphDesc& g) {
    std::vector<std::string> r;
    for (const auto& e : g.edges)
        r.push_back(e.fromPass + "." + e.fromPort + (e.history ? " ~> " : " -> ") + e.toPass + "." +
                    e.toPort);
    return r;
}

TEST(Groups, InstancesExpandIntoFlatPassesNamedByInstancePath) {
    const GraphDesc g = parseGraph(kTwoInstances);
    std::vector<std::string> names;
    for (const auto& p : g.passes) names.push_back(p.name);
    EXPECT_EQ(names, (std::vector<std::string>{"src", "p.a", "p.b", "p.n", "q.a", "q.b", "q.n"}));
    EXPECT_EQ(edgeList(g), (std::vector<std::string>{"p.a.out -> p.b.in", "p.n.out ~> p.n.prev",
                                                     "q.a.out -> q.b.in", "q.n.out ~> q.n.prev",
                                                     "src.out -> p.a.in", "src.out -> q.a.in"}));
    // Group outputs resolve to the inner port that feeds them.
    EXPECT_EQ(g.outputs, (std::vector<std::string>{"p.b.out", "q.b.out", "q.n.out"}));
    EXPECT_EQ(findPass(g, "q.b")->instance, "q");
    EXPECT_EQ(findPass(g, "q.b")->origin, "groups.inc.passes[1]");
    ASSERT_EQ(g.instances.size(), 2u);
    EXPECT_EQ(g.instances[1].path, "q");
    EXPECT_EQ(g.instances[1].group, "inc");
}

TEST(Groups, GroupParametersDriveInnerParameters) {
    GraphDesc g = parseGraph(kTwoInstances);
    EXPECT_EQ(paramsOf(g, "p.a")["alpha"], 0.25);  // the default
    EXPECT_EQ(paramsOf(g, "p.b")["alpha"], 0.25);
    EXPECT_EQ(paramsOf(g, "q.a")["alpha"], 0.75);  // the instance's value
    EXPECT_EQ(paramsOf(g, "q.b")["alpha"], 0.75);
    EXPECT_EQ(paramsOf(g, "q.b")["count"], 3);  // not bound: as written
    // --set on the group parameter reaches every bound inner parameter of that instance only.
    applyOverride(g, "q.alpha=0.5");
    EXPECT_EQ(paramsOf(g, "q.a")["alpha"], 0.5);
    EXPECT_EQ(paramsOf(g, "q.b")["alpha"], 0.5);
    EXPECT_EQ(paramsOf(g, "p.a")["alpha"], 0.25);
    // A pattern over instances sets the group parameter of each; one over instance paths of
    // passes sets the passes' own parameter.
    applyOverride(g, "*.alpha=0.125");
    for (const char* n : {"p.a", "p.b", "q.a", "q.b"}) EXPECT_EQ(paramsOf(g, n)["alpha"], 0.125);
    EXPECT_FALSE(paramsOf(g, "src").contains("alpha"));
    applyOverride(g, "*.b.count=7");
    EXPECT_EQ(paramsOf(g, "p.b")["count"], 7);
    EXPECT_EQ(paramsOf(g, "q.b")["count"], 7);
    EXPECT_FALSE(paramsOf(g, "p.a").contains("count"));
    applyOverride(g, "p.a.count=9");  // one inner pass by its instance path
    EXPECT_EQ(paramsOf(g, "p.a")["count"], 9);
    EXPECT_THROW(applyOverride(g, "q.nosuch=1"), Error);
}

TEST(Groups, ExpandedGraphCompilesAndRunsWithHistoryInsideTheGroup) {
    Registry r = testRegistry();
    const GraphDesc g = parseGraph(kTwoInstances);
    auto compiled = compileGraph(g, r);
    Parallel parallel(1);
    Executor exec(*compiled, parallel, {}, Extent{2, 1});
    exec.beginRun(1, 3);
    for (int f = 1; f <= 3; ++f) exec.runFrame(f, false);
    // Const 1, two AddOne: 3. Counter fed back through the group's history edge: 3 frames.
    EXPECT_FLOAT_EQ(exec.output("q.b.out").channel(0)[0], 3.f);
    EXPECT_FLOAT_EQ(exec.output("q.n.out").channel(0)[0], 3.f);
}

// A history edge may start at a group input: the inner edge marks it, the outer edge is plain.
TEST(Groups, HistoryEdgeFromAGroupInput) {
    const std::string text = R"({"kestrel": 1, "groups": {"prev": {
            "inputs": ["x"], "outputs": ["y"],
            "passes": [{"name": "p", "type": "Previous"}],
            "edges": [{"from": "in.x", "to": "p.prev", "history": true},
                      {"from": "p.out", "to": "out.y"}]}},
        "passes": [{"name": "n", "type": "Counter"}, {"name": "i", "group": "prev"}],
        "edges": [{"from": "n.out", "to": "n.prev", "history": true},
                  {"from": "n.out", "to": "i.x"}],
        "outputs": ["i.y"]})";
    const GraphDesc g = parseGraph(text);
    EXPECT_EQ(edgeList(g), (std::vector<std::string>{"n.out ~> n.prev", "n.out ~> i.p.prev"}));
    Registry r = testRegistry();
    auto compiled = compileGraph(g, r);
    Parallel parallel(1);
    Executor exec(*compiled, parallel, {}, Extent{2, 1});
    exec.beginRun(1, 3);
    for (int f = 1; f <= 3; ++f) exec.runFrame(f, false);
    EXPECT_FLOAT_EQ(exec.output("i.p.out").channel(0)[0], 2.f);  // last frame's count
}

TEST(Groups, NestedInstancesPassParametersDown) {
    const std::string text = std::string(R"({"kestrel": 1, "groups": {
        "inc": {"inputs": ["x"], "outputs": ["y"], "params": {"alpha": 0.25},
                "passes": [{"name": "a", "type": "AddOne", "params": {"alpha": "$alpha"}}],
                "edges": [{"from": "in.x", "to": "a.in"}, {"from": "a.out", "to": "out.y"}]},
        "twice": {"inputs": ["x"], "outputs": ["y"], "params": {"w": 0.5},
                  "passes": [{"name": "one", "group": "inc", "params": {"alpha": "$w"}},
                             {"name": "two", "group": "inc"}],
                  "edges": [{"from": "in.x", "to": "one.x"}, {"from": "one.y", "to": "two.x"},
                            {"from": "two.y", "to": "out.y"}]}},
        "passes": [{"name": "src", "type": "Const"}, {"name": "t", "group": "twice"}],
        "edges": [{"from": "src.out", "to": "t.x"}], "outputs": ["t.y"]})");
    GraphDesc g = parseGraph(text);
    EXPECT_EQ(edgeList(g),
              (std::vector<std::string>{"t.one.a.out -> t.two.a.in", "src.out -> t.one.a.in"}));
    EXPECT_EQ(g.outputs, (std::vector<std::string>{"t.two.a.out"}));
    EXPECT_EQ(paramsOf(g, "t.one.a")["alpha"], 0.5);
    EXPECT_EQ(paramsOf(g, "t.two.a")["alpha"], 0.25);
    applyOverride(g, "t.w=0.125");  // the outer parameter reaches the inner pass through "$w"
    EXPECT_EQ(paramsOf(g, "t.one.a")["alpha"], 0.125);
    EXPECT_EQ(paramsOf(g, "t.two.a")["alpha"], 0.25);
    Registry r = testRegistry();
    const std::string dot = compileGraph(g, r)->toDot();
    EXPECT_NE(dot.find("subgraph \"cluster_t\""), std::string::npos) << dot;
    // The inner instance's cluster sits inside the outer one.
    const auto outer = dot.find("subgraph \"cluster_t\""),
               inner = dot.find("subgraph \"cluster_t.one\"");
    ASSERT_NE(inner, std::string::npos) << dot;
    EXPECT_GT(inner, outer);
    EXPECT_NE(dot.find("\"t.one.a\" [label"), std::string::npos);
}

/// The diagnostics of a graph that must fail to parse or compile.
std::vector<Diagnostic> errorsOf(const std::string& text) {
    Registry r = testRegistry();
    try {
        compileGraph(parseGraph(text), r);
    } catch (const GraphError& e) {
        return e.diagnostics();
    }
    ADD_FAILURE() << "graph was accepted:\n" << text;
    return {};
}

::testing::AssertionResult has(const std::vector<Diagnostic>& diags, const std::string& str) {
    std::string all;
    for (const auto& d : diags) {
        if (d.str().find(str) != std::string::npos) return ::testing::AssertionSuccess();
        all += "  " + d.str() + "\n";
    }
    return ::testing::AssertionFailure() << "no diagnostic with '" << str << "' among:\n" << all;
}

// A bad value inside an instance: one line naming the JSON path in the definition, the instance
// path of the parameter, and the group parameter that set it.
TEST(Groups, ErrorsInsideAnInstanceNameTheInstancePathAndTheDefinition) {
    const auto diags = errorsOf(graphWith(R"([{"name": "src", "type": "Const"},
        {"name": "q", "group": "inc", "params": {"alpha": 5}}])",
                                          R"([{"from": "src.out", "to": "q.x"}])", R"(["q.y"])"));
    EXPECT_TRUE(has(diags, "groups.inc.passes[0].params.alpha (q.a.alpha): "));
    EXPECT_TRUE(has(diags, "(set by group parameter q.alpha)"));
    EXPECT_TRUE(has(diags, "groups.inc.passes[1].params.alpha (q.b.alpha): "));
    // An inner input the instance leaves unconnected names the inner pass by its path.
    EXPECT_TRUE(has(errorsOf(graphWith(R"([{"name": "q", "group": "inc"}])", "[]", R"(["q.y"])")),
                    "groups.inc.passes[0] (q.a): required input 'in' of pass 'q.a'"));
}

TEST(Groups, StructuralErrors) {
    auto one = [](const std::string& passes, const std::string& edges = "[]") {
        return errorsOf(graphWith(passes, edges));
    };
    EXPECT_TRUE(has(one(R"([{"name": "q", "group": "incc"}])"),
                    "passes[0].group: unknown group 'incc' (did you mean 'inc'?)"));
    EXPECT_TRUE(has(one(R"([{"name": "q", "group": "inc", "params": {"alpah": 1}}])"),
                    "passes[0].params.alpah: group 'inc' has no parameter 'alpah' (did you mean "
                    "'alpha'?)"));
    EXPECT_TRUE(has(one(R"([{"name": "s", "type": "Const"}, {"name": "q", "group": "inc"}])",
                        R"([{"from": "s.out", "to": "q.z"}])"),
                    "edges[0].to: instance 'q' (group inc) has no input 'z' (inputs: x)"));
    EXPECT_TRUE(
        has(one(R"([{"name": "q", "group": "inc"}, {"name": "k", "type": "Sink"}])",
                R"([{"from": "q.w", "to": "k.in"}])"),
            "edges[0].from: instance 'q' (group inc) has no output 'w' (outputs: y, count)"));
    // Inside a definition: an unknown "$parameter", an undeclared input, a group using itself.
    EXPECT_TRUE(has(errorsOf(R"({"kestrel": 1, "groups": {"g": {"outputs": ["y"],
        "passes": [{"name": "a", "type": "Const", "params": {"value": "$v"}}],
        "edges": [{"from": "a.out", "to": "out.y"}]}},
        "passes": [{"name": "i", "group": "g"}], "outputs": ["i.y"]})"),
                    "groups.g.passes[0].params.value: unknown group parameter '$v'"));
    EXPECT_TRUE(has(errorsOf(R"({"kestrel": 1, "groups": {"g": {"outputs": ["y"],
        "passes": [{"name": "a", "type": "AddOne"}],
        "edges": [{"from": "in.x", "to": "a.in"}, {"from": "a.out", "to": "out.y"}]}},
        "passes": [{"name": "i", "group": "g"}]})"),
                    "groups.g.edges[0].from: group 'g' declares no input 'x'"));
    EXPECT_TRUE(has(errorsOf(R"({"kestrel": 1, "groups": {
        "a": {"passes": [{"name": "x", "group": "b"}]},
        "b": {"passes": [{"name": "y", "group": "a"}]}},
        "passes": [{"name": "i", "group": "a"}]})"),
                    "groups.b.passes[0].group: group cycle: a -> b -> a"));
}

/// Writes files into a fresh folder; returns it.
fs::path files(const std::vector<std::pair<std::string, std::string>>& contents) {
    static int n = 0;
    const fs::path dir = testutil::processTempDir() / ("files-" + std::to_string(n++));
    for (const auto& [name, text] : contents) {
        fs::create_directories((dir / name).parent_path());
        std::ofstream(dir / name) << text;
    }
    return dir;
}

TEST(Groups, IncludeReadsDefinitionsRelativeToTheIncludingFile) {
    const std::string lib = std::string(R"({"kestrel": 1, )") + kGroup + "}";
    const fs::path dir =
        files({{"lib/inc.json", lib}, {"g.json", R"({"kestrel": 1, "include": ["lib/inc.json"],
        "passes": [{"name": "s", "type": "Const"}, {"name": "q", "group": "inc"}],
        "edges": [{"from": "s.out", "to": "q.x"}], "outputs": ["q.y"]})"}});
    const GraphDesc g = loadGraphFile(dir / "g.json");
    ASSERT_NE(findPass(g, "q.b"), nullptr);
    EXPECT_EQ(findPass(g, "q.b")->origin,
              (dir / "lib/inc.json").string() + ": groups.inc.passes[1]");
    const auto groups = listGroups(dir / "lib/inc.json");
    ASSERT_EQ(groups.size(), 1u);
    EXPECT_EQ(groups[0].name, "inc");
    EXPECT_EQ(groups[0].inputs, (std::vector<std::string>{"x"}));
    EXPECT_EQ(groups[0].passCount, 3u);
    EXPECT_TRUE(listGroups(dir / "g.json").empty());  // it includes the group, defines none
}

TEST(Groups, IncludeCycleIsRefusedWithTheCycleNamed) {
    const fs::path dir = files({{"a.json", R"({"kestrel": 1, "include": ["lib/b.json"]})"},
                                {"lib/b.json", R"({"kestrel": 1, "include": ["../a.json"]})"},
                                {"g.json", R"({"kestrel": 1, "include": ["a.json"],
                                               "passes": []})"}});
    try {
        loadGraphFile(dir / "g.json");
        FAIL() << "include cycle accepted";
    } catch (const GraphError& e) {
        const std::string a = (dir / "a.json").string(), b = (dir / "lib/b.json").string();
        EXPECT_NE(std::string(e.what()).find("include cycle: " + a + " -> " + b + " -> " + a),
                  std::string::npos)
            << e.what();
    }
    // A graph including itself.
    const fs::path self =
        files({{"g.json", R"({"kestrel": 1, "include": ["g.json"], "passes": []})"}});
    EXPECT_THROW(loadGraphFile(self / "g.json"), GraphError);
}

TEST(Groups, ExtendsDropsPassesAndTheirEdges) {
    const fs::path dir =
        files({{"base.json", R"({"kestrel": 1, "passes": [{"name": "s", "type": "Const"},
            {"name": "a", "type": "AddOne"}, {"name": "b", "type": "AddOne"}],
            "edges": [{"from": "s.out", "to": "a.in"}, {"from": "a.out", "to": "b.in"}],
            "outputs": ["b.out"]})"},
               {"v.json", R"({"kestrel": 1, "extends": "base.json", "drop": ["a"],
            "passes": [{"name": "s", "type": "Const", "params": {"value": 2}}],
            "edges": [{"from": "s.out", "to": "b.in"}]})"},
               {"bad.json", R"({"kestrel": 1, "extends": "base.json", "drop": ["zz"]})"}});
    const GraphDesc g = loadGraphFile(dir / "v.json");
    EXPECT_EQ(edgeList(g), (std::vector<std::string>{"s.out -> b.in"}));
    EXPECT_EQ(paramsOf(g, "s")["value"], 2);  // replaced in place
    EXPECT_EQ(findPass(g, "a"), nullptr);
    EXPECT_EQ(g.outputs, (std::vector<std::string>{"b.out"}));
    try {
        loadGraphFile(dir / "bad.json");
        FAIL() << "dropping an unknown pass accepted";
    } catch (const GraphError& e) {
        EXPECT_NE(std::string(e.what()).find("drop: the base graph has no pass 'zz'"),
                  std::string::npos)
            << e.what();
    }
}

}  // namespace
}  // namespace kestrel::enginetest
