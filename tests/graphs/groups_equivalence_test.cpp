// The shipped SVGF graphs written with groups (graphs/lib/svgf-chain.json, extends/drop) compute
// what the flat graphs they replaced computed. tests/graphs/flat/ keeps those flat
// files as they were before the rewrite, with the graph changes made since written into them
// by a one-off script (commit 4917c75: each chain's colour history mixed by a Mix pass; the
// specular chain's atrous3 and atrous4 given iterations 3, so they pass through and are left out
// as in the group; the A-Trous steps 4, 8 and 16 given sigmaL 2.5, the chain's sigmaLWide): their
// pass "diffuse_atrous0" is the instance path "diffuse.atrous0" now (the first '_' of a chain pass
// became the instance's '.').
#include <gtest/gtest.h>
#include <kestrel/Compiler.h>
#include <kestrel/Executor.h>
#include <scenegen/SceneGen.h>

#include <algorithm>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <regex>
#include <set>
#include <tuple>

#include "../GraphTestUtil.h"
#include "../TempDir.h"

namespace fs = std::filesystem;
using namespace kestrel;
using nlohmann::json;

namespace {

const char* const kGraphs[] = {"svgf.json", "svgf-notaa.json", "svgf-split.json"};

fs::path shipped(const std::string& name) {
    return fs::path(KESTREL_SOURCE_DIR) / "graphs" / name;
}
fs::path flat(const std::string& name) {
    return fs::path(KESTREL_SOURCE_DIR) / "tests" / "graphs" / "flat" / name;
}

/// The flat file's pass name as an instance path: diffuse_atrous0 -> diffuse.atrous0.
std::string instancePath(const std::string& flatName) {
    static const std::regex chain("^(diffuse|specular|single)_(.+)$");
    return std::regex_replace(flatName, chain, "$1.$2");
}

/// Every parameter of a pass, declared defaults filled in: a group that writes a default out
/// ("sigmaL": "$sigmaL" with 4.0) sets what the flat file left to the default. ATrous's
/// iteration/iterations (which the chain sets and the flat files mostly predate) are compared
/// only as whether the pass is left out (iteration >= iterations): the same passes must run on
/// both sides (the specular chain's atrous3-4 in neither); IterationsParameter tests the rest.
json effectiveParams(const PassNode& p) {
    const PassType* t = testutil::builtPlugins().find(p.type);
    EXPECT_NE(t, nullptr) << p.type;
    json all = json::object();
    if (t)
        for (const auto& d : t->desc.params)
            all[d.name] = std::visit([](const auto& x) { return json(x); }, d.defaultValue);
    const json set = json::parse(p.paramsJson);
    for (const auto& [k, v] : set.items()) all[k] = v;
    if (p.type == "ATrous") {
        all["leftOut"] = all.value("iteration", 0) >= all.value("iterations", 0);
        EXPECT_EQ(all["leftOut"], p.name.find("specular") != std::string::npos &&
                                      (p.name.ends_with("atrous3") || p.name.ends_with("atrous4")))
            << p.name;
        all.erase("iteration");
        all.erase("iterations");
    }
    return all;
}

using PassKey = std::tuple<std::string, std::string, std::string>;  // name, type, params
using EdgeKey = std::tuple<std::string, std::string, bool>;         // from, to, history

std::multiset<PassKey> passesOf(const GraphDesc& g, bool rename) {
    std::multiset<PassKey> s;
    for (const auto& p : g.passes)
        s.insert({rename ? instancePath(p.name) : p.name, p.type, effectiveParams(p).dump()});
    return s;
}

std::multiset<EdgeKey> edgesOf(const GraphDesc& g, bool rename) {
    auto n = [&](const std::string& pass) { return rename ? instancePath(pass) : pass; };
    std::multiset<EdgeKey> s;
    for (const auto& e : g.edges)
        s.insert({n(e.fromPass) + "." + e.fromPort, n(e.toPass) + "." + e.toPort, e.history});
    return s;
}

// The expansion of each shipped graph is the flat graph: the same passes with the same types and
// parameters, the same edges (history flags included), nothing more.
TEST(ShippedGroups, ExpandToTheFlatGraphs) {
    for (const char* name : kGraphs) {
        SCOPED_TRACE(name);
        const GraphDesc grouped = loadGraphFile(shipped(name));
        const GraphDesc old = loadGraphFile(flat(name));
        EXPECT_EQ(passesOf(grouped, false), passesOf(old, true));
        EXPECT_EQ(edgesOf(grouped, false), edgesOf(old, true));
        EXPECT_EQ(grouped.passes.size(), old.passes.size());
        EXPECT_EQ(grouped.edges.size(), old.edges.size());
        EXPECT_EQ(grouped.outputs, old.outputs);
    }
}

// One edit changes every chain: the group parameters' defaults drive the five A-Trous iterations
// of all three chains (sigmaL steps 1 and 2, sigmaLWide steps 4 to 16), and --set on them (or on
// an instance) reaches exactly those.
TEST(ShippedGroups, OneSigmaForEveryChain) {
    for (bool set : {false, true}) {
        GraphDesc g = loadGraphFile(shipped("svgf.json"));
        if (set) {
            applyOverride(g, "*.sigmaL=6");
            applyOverride(g, "*.sigmaLWide=3");
        }
        const double narrow = set ? 6.0 : 4.0, wide = set ? 3.0 : 2.5;
        int atrous = 0;
        for (const auto& p : g.passes) {
            const json params = json::parse(p.paramsJson);
            std::smatch m;
            const bool iteration = std::regex_match(p.name, m, std::regex(R"(\w+\.atrous([0-4]))"));
            atrous += iteration;
            if (iteration)  // steps 1 and 2 take sigmaL, steps 4, 8 and 16 sigmaLWide
                EXPECT_EQ(params.value("sigmaL", 0.0), m[1] < "2" ? narrow : wide) << p.name;
            else
                EXPECT_FALSE(params.contains("sigmaL") && params["sigmaL"] == narrow) << p.name;
        }
        EXPECT_EQ(atrous, 15);
    }
}

/// Each frame's output of `graph` (its writer replaced by a marked output), as raw floats; or
/// the compile error's message when the graph cannot run on the scene.
struct Outputs {
    std::vector<std::vector<float>> frames;
    std::string error;
};

Outputs run(const fs::path& graph, const std::string& input, int64_t first, int64_t last) {
    GraphDesc g = loadGraphFile(graph);
    applyOverride(g, "input.path=" + json(input).dump());
    const std::string marked = testutil::markWriterInput(g);
    CompileOptions copt;
    copt.firstFrame = first;
    Outputs out;
    std::unique_ptr<CompiledGraph> compiled;
    try {
        compiled = compileGraph(g, testutil::builtPlugins(), copt);
    } catch (const Error& e) {
        out.error = e.what();
        return out;
    }
    Parallel parallel(2);
    Executor exec(*compiled, parallel);
    exec.beginRun(first, last);
    for (int64_t f = first; f <= last; ++f) {
        exec.runFrame(f, false);
        const ImageView& o = exec.output(marked);
        auto& v = out.frames.emplace_back();
        for (int c = 0; c < o.channels(); ++c)
            v.insert(v.end(), o.channel(c), o.channel(c) + o.pixels());
    }
    return out;
}

/// Runs every shipped SVGF graph and its flat original on a sequence: bit-identical frames.
void expectBitIdentical(const std::string& input, int64_t first, int64_t last) {
    int ran = 0;
    for (const char* name : kGraphs) {
        SCOPED_TRACE(std::string(name) + " on " + input);
        const Outputs a = run(shipped(name), input, first, last);
        const Outputs b = run(flat(name), input, first, last);
        // svgf-split needs the diffuse/specular split: both refuse a scene without it, alike
        // but for the pass names in the message.
        EXPECT_EQ(a.error.empty(), b.error.empty()) << a.error << " | " << b.error;
        ASSERT_EQ(a.frames.size(), b.frames.size());
        for (size_t i = 0; i < a.frames.size(); ++i) {
            ASSERT_EQ(a.frames[i].size(), b.frames[i].size());
            EXPECT_EQ(std::memcmp(a.frames[i].data(), b.frames[i].data(),
                                  a.frames[i].size() * sizeof(float)),
                      0)
                << "frame " << first + int64_t(i) << " differs";
        }
        ran += !a.frames.empty();
    }
    EXPECT_GE(ran, 2);  // svgf and svgf-notaa run on every scene
}

fs::path scene(const std::string& name, scenegen::SceneOptions opt) {
    const fs::path dir = testutil::processTempDir() / name;
    if (!fs::exists(dir / "done")) {
        fs::create_directories(dir);
        scenegen::writeSequence(opt, dir);
        std::ofstream(dir / "done") << "1";
    }
    return dir;
}

/// The built-in room, 64x48, 4 frames (point-sampled, one illumination: the single chain, no
/// TAA), as the loader's input pattern.
std::string builtInRoom() {
    scenegen::SceneOptions o;
    o.width = 64;
    o.height = 48;
    o.frames = 4;
    o.referenceSpp = 1;
    return (scene("room", o) / "noisy/frame_####.exr").string();
}

TEST(ShippedGroups, BitIdenticalOnTheBuiltInScene) {
    expectBitIdentical(builtInRoom(), 1, 4);
}

// The zoo street with a 1.5 px pixel filter: the diffuse/specular split, albedo averaging, TAA.
TEST(ShippedGroups, BitIdenticalOnAnAntiAliasedSplitScene) {
    auto o = scenegen::zooScene("street-jittered").options;
    o.frames = 4;
    o.referenceSpp = 1;
    expectBitIdentical((scene("street-jittered", o) / "noisy/frame_####.exr").string(), 1, 4);
}

// Blender Cycles renders: point-sampled with the split (blender-street), anti-aliased without
// it (blender-street-defaults).
TEST(ShippedGroups, BitIdenticalOnBlenderSequences) {
    int found = 0;
    for (const char* seq : {"blender-street", "blender-street-defaults"}) {
        const fs::path dir = fs::path(KESTREL_SHARED_DIR) / "data" / seq;
        if (!fs::exists(dir / "noisy" / "frame_0001.exr")) continue;
        ++found;
        expectBitIdentical((dir / "noisy/frame_####.exr").string(), 1, 3);
    }
    if (!found) GTEST_SKIP() << "../shared/data/blender-street* not present (a user's clone)";
}

/// The flat svgf-notaa.json with A-Trous iterations `keep` and beyond cut out of every chain, the
/// last kept iteration feeding what the cut ones fed, and the colour history resampled bilinearly:
/// the chains svgf-fast.json's parameters ask for, written out by hand.
fs::path flatWithIterations(int keep) {
    json g = json::parse(std::ifstream(flat("svgf.json")));
    const std::regex iteration(R"(^(\w+)_atrous(\d)$)");
    auto cut = [&](const std::string& pass) {
        std::smatch m;
        return std::regex_match(pass, m, iteration) && std::stoi(m[2]) >= keep;
    };
    auto passOf = [](const std::string& port) { return port.substr(0, port.find('.')); };
    json passes = json::array();
    const std::regex reprojection(R"(^\w+_reprojection$)");
    for (json p : g["passes"]) {
        if (cut(p["name"])) continue;
        if (std::regex_match(p["name"].get<std::string>(), reprojection))
            p["params"]["filter"] = "bilinear";
        passes.push_back(p);
    }
    g["passes"] = passes;
    json edges = json::array();
    for (json e : g["edges"]) {
        if (e["to"].is_string() && cut(passOf(e["to"]))) continue;
        const std::string from = e["from"];
        if (cut(passOf(from))) {
            const std::string chain = from.substr(0, from.find('_'));
            e["from"] = chain + "_atrous" + std::to_string(keep - 1) + from.substr(from.find('.'));
        }
        edges.push_back(e);
    }
    g["edges"] = edges;
    const fs::path file = testutil::processTempDir() / "iterations.json";
    std::ofstream(file) << g.dump(1);
    return file;
}

std::vector<std::string> livePasses(const fs::path& graph, const std::string& input) {
    GraphDesc g = loadGraphFile(graph);
    applyOverride(g, "input.path=" + json(input).dump());
    testutil::markWriterInput(g);
    CompileOptions copt;
    copt.firstFrame = 1;
    return compileGraph(g, testutil::builtPlugins(), copt)->executionOrder();
}

// One parameter sets a chain's A-Trous iteration count: svgf-fast.json (iterations 2) runs
// exactly iterations 0 and 1 of its chain, bit-identical to the flat graph with 2-4 cut out.
TEST(ShippedGroups, IterationsParameterRunsExactlyThatManyIterations) {
    const std::string input = builtInRoom();
    const fs::path cutFlat = flatWithIterations(2);
    const Outputs fast = run(shipped("svgf-fast.json"), input, 1, 4);
    const Outputs expected = run(cutFlat, input, 1, 4);
    const Outputs full = run(shipped("svgf.json"), input, 1, 4);
    fs::remove(cutFlat);
    ASSERT_TRUE(fast.error.empty()) << fast.error;
    ASSERT_EQ(fast.frames.size(), expected.frames.size());
    for (size_t i = 0; i < fast.frames.size(); ++i) {
        EXPECT_EQ(fast.frames[i], expected.frames[i]) << "frame " << i + 1;
        EXPECT_NE(fast.frames[i], full.frames[i]) << "frame " << i + 1;
    }
    const auto live = livePasses(shipped("svgf-fast.json"), input);
    auto has = [&](const char* pass) { return std::count(live.begin(), live.end(), pass) > 0; };
    EXPECT_TRUE(has("single.atrous0") && has("single.atrous1"));
    EXPECT_FALSE(has("single.atrous2") || has("single.atrous3") || has("single.atrous4"));
}

}  // namespace
