// kestrel CLI, end to end: exit codes (0 ok, 1 runtime failure, 2 usage or graph error), one clear
// error line per problem, help on every subcommand, the pass listing and the DOT export.
#include <fstream>
#include <iterator>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "CliRunner.h"

using namespace clitest;

namespace {

void expectClean(const CliResult& r) {
    EXPECT_FALSE(looksLikeCrash(r.out + r.err)) << r.all();
}

}  // namespace

TEST(CliUsage, UnknownSubcommandIsAUsageError) {
    Sandbox box;
    auto r = box.run({"frobnicate"});
    EXPECT_EQ(r.code, 2) << r.all();
    expectOneError(r, {"frobnicate"});
    expectClean(r);
}

TEST(CliUsage, UnknownOptionIsAUsageError) {
    Sandbox box;
    auto r = box.run({"run", "--no-such-option"});
    EXPECT_EQ(r.code, 2) << r.all();
    expectOneError(r, {"--no-such-option"});
    expectClean(r);
}

TEST(CliUsage, HelpOnEverySubcommandExitsZero) {
    Sandbox box;
    auto top = box.run({"--help"});
    EXPECT_EQ(top.code, 0) << top.all();
    for (const char* sub : {"run", "validate", "passes", "graph"}) {
        EXPECT_NE(top.out.find(sub), std::string::npos) << "top-level help does not list " << sub;
        auto r = box.run({sub, "--help"});
        EXPECT_EQ(r.code, 0) << sub << "\n" << r.all();
        EXPECT_NE(r.out.find("Usage"), std::string::npos) << sub << "\n" << r.all();
        EXPECT_TRUE(r.errorLines().empty()) << sub << "\n" << r.all();
        expectClean(r);
    }
    // Optional subcommands, when this build has them.
    for (const char* sub : {"scenegen", "compare", "bench"}) {
        if (top.out.find(sub) == std::string::npos) continue;
        auto r = box.run({sub, "--help"});
        EXPECT_EQ(r.code, 0) << sub << "\n" << r.all();
        expectClean(r);
    }
}

TEST(CliUsage, ValidateAcceptsAGoodGraph) {
    Sandbox box;
    auto r = box.run({"validate", (graphDir() / "taa.json").string()});
    EXPECT_EQ(r.code, 0) << r.all();
    EXPECT_NE(r.out.find("ok"), std::string::npos) << r.all();
    EXPECT_TRUE(r.errorLines().empty()) << r.all();
}

TEST(CliUsage, ValidatePrintsEveryDiagnostic) {
    Sandbox box;
    auto r = box.run({"validate", (graphDir() / "errors.json").string()});
    EXPECT_EQ(r.code, 2) << r.all();
    expectClean(r);
    // errors.json has independent mistakes: all three are reported, one line each.
    auto lines = r.errorLines();
    EXPECT_GE(lines.size(), 3u) << r.all();
    auto has = [&](const char* needle) {
        for (const auto& l : lines)
            if (l.find(needle) != std::string::npos) return true;
        return false;
    };
    EXPECT_TRUE(has("NoSuchPassType")) << r.all();
    EXPECT_TRUE(has("alpha")) << r.all();
    EXPECT_TRUE(has("colour")) << r.all();
}

TEST(CliUsage, SyntaxErrorGivesLineAndColumn) {
    Sandbox box;
    // Line 3 misses a comma after the "name" member: the parser stops at line 4.
    writeText(box.work() / "broken.json",
              "{\n  \"kestrel\": 1,\n  \"name\": \"broken\"\n  \"passes\": []\n}\n");
    auto r = box.run({"validate", "broken.json"});
    EXPECT_EQ(r.code, 2) << r.all();
    expectOneError(r, {"broken.json:4:"});
    expectClean(r);
}

TEST(CliUsage, MissingGraphFileNamesTheFile) {
    Sandbox box;
    for (const char* sub : {"validate", "run", "graph"}) {
        auto r = box.run({sub, "no-such-graph.json"});
        EXPECT_EQ(r.code, 2) << sub << "\n" << r.all();
        expectOneError(r, {"no-such-graph.json"});
        expectClean(r);
    }
}

TEST(CliUsage, SetOfUnknownPassNamesIt) {
    Sandbox box;
    auto r = box.run({"run", (graphDir() / "taa.json").string(), "--input", "none.####.exr",
                      "--frames", "1", "--set", "nosuch.alpha=0.5"});
    EXPECT_EQ(r.code, 2) << r.all();
    expectOneError(r, {"nosuch.alpha"});
    expectClean(r);
}

TEST(CliUsage, SetOfUnknownParameterNamesPassDotParam) {
    Sandbox box;
    auto r = box.run({"validate", (graphDir() / "taa.json").string()});
    ASSERT_EQ(r.code, 0) << r.all();
    r = box.run({"run", (graphDir() / "taa.json").string(), "--input", "none.####.exr", "--frames",
                 "1", "--set", "taa.alhpa=0.5"});
    EXPECT_EQ(r.code, 2) << r.all();
    expectOneError(r, {"taa.alhpa"});
    expectClean(r);
}

TEST(CliUsage, SetOutOfRangeNamesPassDotParamAndRange) {
    Sandbox box;
    auto r = box.run({"run", (graphDir() / "taa.json").string(), "--input", "none.####.exr",
                      "--frames", "1", "--set", "taa.alpha=1.5"});
    EXPECT_EQ(r.code, 2) << r.all();
    expectOneError(r, {"taa.alpha", "1.5"});
    expectClean(r);
}

TEST(CliUsage, PassesListsTypesWithParams) {
    Sandbox box;
    auto r = box.run({"passes"});
    ASSERT_EQ(r.code, 0) << r.all();
    EXPECT_NE(r.out.find("ExrLoader"), std::string::npos);
    EXPECT_NE(r.out.find("param path"), std::string::npos);
    expectClean(r);
}

TEST(CliUsage, PassesJsonIsValidJson) {
    Sandbox box;
    auto r = box.run({"passes", "--json"});
    ASSERT_EQ(r.code, 0) << r.all();
    nlohmann::json j;
    ASSERT_NO_THROW(j = nlohmann::json::parse(r.out)) << r.out;
    ASSERT_TRUE(j.is_array());
    const nlohmann::json* loader = nullptr;
    for (const auto& t : j)
        if (t.value("type", "") == "ExrLoader") loader = &t;
    ASSERT_NE(loader, nullptr) << "ExrLoader missing from passes --json";
    bool hasPath = false;
    for (const auto& p : (*loader)["params"])
        if (p["name"] == "path" && p["type"] == "string") hasPath = true;
    EXPECT_TRUE(hasPath) << loader->dump(2);
    bool hasColor = false;
    for (const auto& p : (*loader)["ports"])
        if (p["name"] == "color" && p["kind"] == "output") hasColor = true;
    EXPECT_TRUE(hasColor) << loader->dump(2);
    // Ranged parameters carry their range: TAA's alpha is in [0, 1].
    for (const auto& t : j)
        if (t["type"] == "TAA")
            for (const auto& p : t["params"])
                if (p["name"] == "alpha") {
                    EXPECT_EQ(p["range"][0].get<double>(), 0.0);
                    EXPECT_EQ(p["range"][1].get<double>(), 1.0);
                }
}

TEST(CliUsage, GraphDotShowsHistoryEdgesDashed) {
    Sandbox box;
    if (!makeScene(box, box.work() / "scene", 16, 12, 1))
        GTEST_SKIP() << "no scenegen in this build";
    auto r = box.run({"graph", (graphDir() / "taa.json").string(), "--dot", "--all", "--input",
                      "scene/noisy/frame_####.exr"});
    ASSERT_EQ(r.code, 0) << r.all();
    EXPECT_NE(r.out.find("digraph"), std::string::npos) << r.out;
    // The TAA feedback edge (taa.color -> taa.history of the next frame) is dashed.
    bool dashedHistory = false;
    std::istringstream s(r.out);
    for (std::string l; std::getline(s, l);)
        if (l.find("dashed") != std::string::npos && l.find("history") != std::string::npos)
            dashedHistory = true;
    EXPECT_TRUE(dashedHistory) << r.out;
    expectClean(r);
    // The default (collapsed) view draws the same feedback dashed.
    r = box.run({"graph", (graphDir() / "taa.json").string(), "--dot", "--input",
                 "scene/noisy/frame_####.exr"});
    ASSERT_EQ(r.code, 0) << r.all();
    EXPECT_NE(r.out.find("\"taa\" -> \"reproject\" [label=\"taa.color\", style=dashed"),
              std::string::npos)
        << r.out;
}

// --light-change F --light-scale K changes a street scene's lights from frame F on (the frames
// before are byte for byte the plain street's); the room, which has no such light, refuses it.
TEST(CliUsage, ScenegenLightChangeFromItsFrameOn) {
    Sandbox box;
    auto gen = [&](const char* dir, std::vector<std::string> extra) {
        std::vector<std::string> args{"scenegen", "--out",    dir, "--width", "16", "--height",
                                      "12",       "--frames", "3", "--spp",   "2"};
        args.insert(args.end(), extra.begin(), extra.end());
        return box.run(args);
    };
    auto r = gen("plain", {"--scene", "street"});
    ASSERT_EQ(r.code, 0) << r.all();
    r = gen("dimmed", {"--scene", "street", "--light-change", "3", "--light-scale", "0"});
    ASSERT_EQ(r.code, 0) << r.all();
    auto bytes = [&](const std::string& f) {
        std::ifstream in(box.work() / f, std::ios::binary);
        return std::string(std::istreambuf_iterator<char>(in), {});
    };
    EXPECT_EQ(bytes("plain/ref/frame_0002.exr"), bytes("dimmed/ref/frame_0002.exr"));
    EXPECT_NE(bytes("plain/ref/frame_0003.exr"), bytes("dimmed/ref/frame_0003.exr"));
    r = gen("room", {"--light-change", "2"});
    EXPECT_NE(r.code, 0);
    expectOneError(r, {"room", "light change"});
}
