// Groups on the command line (docs/graphs.md): --set on instance paths, group parameters and
// patterns; errors inside an instance as one line naming the instance path and the definition;
// DOT clusters; `kestrel passes` listing the groups of a graph folder.
#include <algorithm>
#include <nlohmann/json.hpp>
#include <regex>
#include <set>

#include "CliRunner.h"

using namespace clitest;

namespace {

fs::path shipped(const char* name) {
    return fs::path(KESTREL_SOURCE_DIR) / "graphs" / name;
}

class CliGroups : public ::testing::Test {
protected:
    void SetUp() override {
        if (!makeScene(box, box.work() / "scene", 16, 12, 1))
            GTEST_SKIP() << "no scenegen in this build";
    }
    /// `kestrel graph svgf.json` on the tiny scene, with extra arguments.
    CliResult graph(const std::vector<std::string>& extra) {
        std::vector<std::string> args{"graph", shipped("svgf.json").string(), "--input",
                                      "scene/noisy/frame_####.exr"};
        args.insert(args.end(), extra.begin(), extra.end());
        return box.run(args);
    }
    Sandbox box;
};

TEST_F(CliGroups, SetTakesInstancePathsGroupParametersAndPatterns) {
    for (const char* set :
         {"single.atrous2.sigmaL=6", "single.sigmaL=6", "*.sigmaL=6", "*.atrous*.exact=true"}) {
        const CliResult r = graph({"--set", set});
        EXPECT_EQ(r.code, 0) << set << "\n" << r.all();
    }
    // A bad value through a group parameter: one line naming the option as typed, every inner
    // pass it drives and the group parameter (not a shipped graph file).
    const CliResult bad = graph({"--set", "single.sigmaLWide=-1"});
    EXPECT_EQ(bad.code, 2) << bad.all();
    const auto lines = bad.errorLines();
    ASSERT_EQ(lines.size(), 1u) << bad.all();  // atrous2..4 of the single chain (steps 4-16)
    EXPECT_NE(lines[0].find("error: --set single.sigmaLWide=-1 (single.atrous2.sigmaL, "
                            "single.atrous3.sigmaL, single.atrous4.sigmaL): expected number in"),
              std::string::npos)
        << lines[0];
    EXPECT_NE(lines[0].find("(set by group parameter single.sigmaLWide)"), std::string::npos)
        << lines[0];
    EXPECT_EQ(lines[0].find(".json"), std::string::npos) << lines[0];
    // A pattern matching nothing names it.
    const CliResult none = graph({"--set", "*.atrous9.sigmaL=1"});
    EXPECT_EQ(none.code, 2) << none.all();
    ASSERT_EQ(none.errorLines().size(), 1u) << none.all();
    EXPECT_NE(none.errorLines()[0].find("no pass matches '*.atrous9'"), std::string::npos);
}

TEST_F(CliGroups, DotAllDrawsEachInstanceAsACluster) {
    const CliResult r = graph({"--dot", "--all"});
    ASSERT_EQ(r.code, 0) << r.all();
    for (const char* inst : {"diffuse", "specular", "single"}) {
        const auto at = r.out.find("subgraph \"cluster_" + std::string(inst) + "\" {");
        ASSERT_NE(at, std::string::npos) << inst << "\n" << r.out;
        // The instance's passes are declared inside its cluster, before it closes.
        const auto pass = r.out.find("\"" + std::string(inst) + ".atrous0\" [label", at);
        EXPECT_LT(pass, r.out.find("\n  }\n", at)) << inst;
    }
    EXPECT_EQ(r.out.find("subgraph \"cluster_taa"), std::string::npos);  // not an instance
}

namespace {
/// The node names a DOT text declares ("NAME" [label=...) and its edges' endpoints.
std::set<std::string> dotNodes(const std::string& dot) {
    std::set<std::string> nodes;
    const std::regex decl("\n *\"([^\"]+)\" \\[label=");
    for (std::sregex_iterator it(dot.begin(), dot.end(), decl), end; it != end; ++it)
        nodes.insert((*it)[1].str());
    return nodes;
}
std::vector<std::pair<std::string, std::string>> dotEdges(const std::string& dot) {
    std::vector<std::pair<std::string, std::string>> edges;
    const std::regex edge("\n *\"([^\"]+)\" -> \"([^\"]+)\"");
    for (std::sregex_iterator it(dot.begin(), dot.end(), edge), end; it != end; ++it)
        edges.push_back({(*it)[1].str(), (*it)[2].str()});
    return edges;
}
}  // namespace

// The default picture fits a screen: one box per group instance, the passes this scene leaves
// out hidden (the room has no diffuse/specular split: those chains are left out); --all keeps
// the full view.
TEST_F(CliGroups, DotCollapsesInstancesAndHidesLeftOutPasses) {
    const CliResult list = graph({});  // live passes in execution order, then the left-out ones
    ASSERT_EQ(list.code, 0) << list.all();
    std::set<std::string> expected;  // each live pass's box: its instance, else itself
    std::istringstream lines(list.out);
    for (std::string l; std::getline(lines, l) && l.find(' ') == std::string::npos;)
        expected.insert(l.substr(0, l.find('.')));
    ASSERT_TRUE(expected.count("single")) << list.out;

    const CliResult r = graph({"--dot"});
    ASSERT_EQ(r.code, 0) << r.all();
    EXPECT_EQ(dotNodes(r.out), expected) << r.out;
    EXPECT_FALSE(expected.count("diffuse") || expected.count("specular")) << list.out;
    EXPECT_EQ(r.out.find("cluster"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("\"single\" [label=\"single\\n(group svgf-chain)"), std::string::npos)
        << r.out;
    const auto edges = dotEdges(r.out);
    EXPECT_FALSE(edges.empty());
    for (const auto& [from, to] : edges) {
        EXPECT_TRUE(expected.count(from) && expected.count(to)) << from << " -> " << to;
        EXPECT_NE(from, to);
    }
    // The output is reached: the looked-through Select and TAA chain stay connected.
    EXPECT_TRUE(std::any_of(edges.begin(), edges.end(), [](const auto& e) {
        return e.second == "output";
    })) << r.out;

    const CliResult all = graph({"--dot", "--all"});
    ASSERT_EQ(all.code, 0) << all.all();
    const auto allNodes = dotNodes(all.out);
    EXPECT_TRUE(allNodes.count("diffuse.atrous0") && allNodes.count("single.atrous0"));
    EXPECT_GT(allNodes.size(), 3 * expected.size());
}

TEST_F(CliGroups, PassesListsTheGroupsOfAGraphFolder) {
    CliResult r = box.run({"passes"});
    ASSERT_EQ(r.code, 0) << r.all();
    EXPECT_NE(r.out.find("group svgf-chain"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("param sigmaL = 4.0"), std::string::npos) << r.out;
    r = box.run({"passes", "--json"});
    ASSERT_EQ(r.code, 0) << r.all();
    const auto j = nlohmann::json::parse(r.out);
    bool chain = false;
    for (const auto& e : j)
        if (e.value("group", "") == "svgf-chain") {
            chain = true;
            EXPECT_EQ(e["outputs"], nlohmann::json::array({"color", "taps"}));
            EXPECT_EQ(e["params"]["sigmaL"], 4.0);
        }
    EXPECT_TRUE(chain) << r.out;
    // Another folder: its own groups; a broken definition is one error line, exit 2.
    writeText(box.work() / "mine" / "lib" / "g.json", R"({"kestrel": 1, "groups": {"blur": {
        "inputs": ["x"], "outputs": ["y"], "passes": []}}})");
    r = box.run({"passes", "--graphs", "mine"});
    ASSERT_EQ(r.code, 0) << r.all();
    EXPECT_NE(r.out.find("group blur"), std::string::npos) << r.out;
    EXPECT_EQ(r.out.find("group svgf-chain"), std::string::npos) << r.out;
    writeText(box.work() / "mine" / "bad.json", R"({"kestrel": 1, "include": ["bad.json"]})");
    r = box.run({"passes", "--graphs", "mine"});
    EXPECT_EQ(r.code, 2) << r.all();
    ASSERT_EQ(r.errorLines().size(), 1u) << r.all();
    EXPECT_NE(r.errorLines()[0].find("include cycle"), std::string::npos) << r.all();
}

}  // namespace
