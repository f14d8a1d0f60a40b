// The shipped SVGF graphs hold what their files claim, checked without a hand-kept copy of any
// graph (a flat golden copy had to be edited with every graph change): svgf-notaa.json and
// svgf-split.json are svgf.json less the passes they drop plus the edges they add, and compute
// exactly what svgf.json computes where their comments say so (no TAA on point-sampled renders;
// the specular chain's output wherever the render has the diffuse/specular split); one group
// parameter sets every chain's sigmas, and `iterations` runs exactly that many A-Trous passes,
// bit-identical to the same graph with the others cut out.
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

fs::path shipped(const std::string& name) {
    return fs::path(KESTREL_SOURCE_DIR) / "graphs" / name;
}

using PassKey = std::pair<std::string, std::string>;         // name, type + parameters
using EdgeKey = std::tuple<std::string, std::string, bool>;  // from, to, history

std::set<PassKey> passesOf(const GraphDesc& g) {
    std::set<PassKey> s;
    for (const auto& p : g.passes) s.insert({p.name, p.type + " " + p.paramsJson});
    return s;
}

std::multiset<EdgeKey> edgesOf(const GraphDesc& g) {
    std::multiset<EdgeKey> s;
    for (const auto& e : g.edges)
        s.insert({e.fromPass + "." + e.fromPort, e.toPass + "." + e.toPort, e.history});
    return s;
}

/// The derived graph's own file: the passes it drops and the edges it adds ("to" a port or a
/// list of ports), as written.
struct Derivation {
    std::set<std::string> dropped;
    std::multiset<EdgeKey> added;
};

/// Where an svgf-chain instance's outputs come from inside it ("color" -> "modulate.color"), as
/// graphs/lib/svgf-chain.json wires them: an edge from "specular.color" expands to one from
/// "specular.modulate.color".
std::map<std::string, std::string> chainOutputs() {
    const json doc =
        json::parse(std::ifstream(shipped("lib/svgf-chain.json")), nullptr, true, true);
    std::map<std::string, std::string> out;
    for (const auto& e : doc["groups"]["svgf-chain"]["edges"]) {
        const std::string to = e["to"].is_string() ? e["to"].get<std::string>() : "";
        if (to.rfind("out.", 0) == 0) out[to.substr(4)] = e["from"];
    }
    return out;
}

/// "specular.color" as expanded, where "specular" is an svgf-chain instance of `g`.
std::string expandedSource(const GraphDesc& g, const std::string& from) {
    static const auto outputs = chainOutputs();
    const std::string instance = from.substr(0, from.find('.'));
    const std::string port = from.substr(from.find('.') + 1);
    for (const auto& i : g.instances)
        if (i.path == instance && i.group == "svgf-chain" && outputs.count(port))
            return instance + "." + outputs.at(port);
    return from;
}

Derivation derivationOf(const std::string& name) {
    const json doc = json::parse(std::ifstream(shipped(name)), nullptr, true, true);
    Derivation d;
    EXPECT_EQ(doc.value("extends", ""), "svgf.json") << name;
    for (const auto& n : doc.value("drop", json::array())) d.dropped.insert(n.get<std::string>());
    for (const auto& e : doc.value("edges", json::array())) {
        const json to = e["to"].is_array() ? e["to"] : json::array({e["to"]});
        for (const auto& t : to) d.added.insert({e["from"], t, e.value("history", false)});
    }
    return d;
}

/// A pass of the expanded graph belongs to a dropped pass or group instance.
bool droppedBy(const std::string& pass, const std::set<std::string>& dropped) {
    return dropped.count(pass.substr(0, pass.find('.'))) > 0;
}

}  // namespace

// svgf-notaa.json and svgf-split.json expand to svgf.json's passes, less those they drop (whole
// group instances included), with the same types and parameters; and to its edges, less those
// touching a dropped pass, plus their own.
TEST(ShippedGroups, DerivedGraphsAreTheBaseLessWhatTheyDrop) {
    const GraphDesc base = loadGraphFile(shipped("svgf.json"));
    for (const char* name : {"svgf-notaa.json", "svgf-split.json"}) {
        SCOPED_TRACE(name);
        const Derivation d = derivationOf(name);
        const GraphDesc derived = loadGraphFile(shipped(name));
        std::set<PassKey> passes;
        for (const auto& p : passesOf(base))
            if (!droppedBy(p.first, d.dropped)) passes.insert(p);
        EXPECT_EQ(passesOf(derived), passes);
        std::multiset<EdgeKey> edges;
        for (const auto& [from, to, history] : d.added)
            edges.insert({expandedSource(derived, from), to, history});
        for (const auto& e : edgesOf(base))
            if (!droppedBy(std::get<0>(e), d.dropped) && !droppedBy(std::get<1>(e), d.dropped))
                edges.insert(e);
        EXPECT_EQ(edgesOf(derived), edges);
        EXPECT_FALSE(d.dropped.empty());
    }
}

namespace {

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

Outputs run(GraphDesc g, const std::string& input, int64_t first, int64_t last) {
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

Outputs run(const fs::path& graph, const std::string& input, int64_t first, int64_t last) {
    return run(loadGraphFile(graph), input, first, last);
}

void expectSameFrames(const Outputs& a, const Outputs& b, int64_t first) {
    ASSERT_TRUE(a.error.empty()) << a.error;
    ASSERT_TRUE(b.error.empty()) << b.error;
    ASSERT_EQ(a.frames.size(), b.frames.size());
    for (size_t i = 0; i < a.frames.size(); ++i) {
        ASSERT_EQ(a.frames[i].size(), b.frames[i].size());
        EXPECT_EQ(
            std::memcmp(a.frames[i].data(), b.frames[i].data(), a.frames[i].size() * sizeof(float)),
            0)
            << "frame " << first + int64_t(i) << " differs";
    }
}

/// What the derived graphs' comments promise on a sequence: svgf-notaa computes svgf.json's
/// frames where the render is point-sampled (svgf.json leaves its TAA out there), svgf-split
/// computes them where the render has the diffuse/specular split (svgf.json's Select then takes
/// the specular chain) and refuses a render without it.
void expectDerivedAsPromised(const std::string& input, int64_t first, int64_t last,
                             bool pointSampled, bool split) {
    const Outputs svgf = run(shipped("svgf.json"), input, first, last);
    ASSERT_TRUE(svgf.error.empty()) << svgf.error;
    const Outputs notaa = run(shipped("svgf-notaa.json"), input, first, last);
    const Outputs splitOnly = run(shipped("svgf-split.json"), input, first, last);
    if (pointSampled) {
        SCOPED_TRACE("svgf-notaa on " + input);
        expectSameFrames(svgf, notaa, first);
    } else {
        ASSERT_TRUE(notaa.error.empty()) << notaa.error;
        EXPECT_NE(svgf.frames, notaa.frames) << "TAA ran on an anti-aliased render";
    }
    SCOPED_TRACE("svgf-split on " + input);
    if (split)
        expectSameFrames(svgf, splitOnly, first);
    else
        EXPECT_FALSE(splitOnly.error.empty()) << "svgf-split ran without the split";
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

TEST(ShippedGroups, DerivedGraphsAsPromisedOnTheBuiltInScene) {
    expectDerivedAsPromised(builtInRoom(), 1, 4, true, false);
}

// The zoo street with a 1.5 px pixel filter: the diffuse/specular split, albedo averaging, TAA.
TEST(ShippedGroups, DerivedGraphsAsPromisedOnAnAntiAliasedSplitScene) {
    auto o = scenegen::zooScene("street-jittered").options;
    o.frames = 4;
    o.referenceSpp = 1;
    expectDerivedAsPromised((scene("street-jittered", o) / "noisy/frame_####.exr").string(), 1, 4,
                            false, true);
}

// Blender Cycles renders: point-sampled with the split (blender-street), anti-aliased without
// it (blender-street-defaults).
TEST(ShippedGroups, DerivedGraphsAsPromisedOnBlenderSequences) {
    int found = 0;
    for (const char* seq : {"blender-street", "blender-street-defaults"}) {
        const fs::path dir = fs::path(KESTREL_SHARED_DIR) / "data" / seq;
        if (!fs::exists(dir / "noisy" / "frame_0001.exr")) continue;
        ++found;
        const bool street = std::string(seq) == "blender-street";
        expectDerivedAsPromised((dir / "noisy/frame_####.exr").string(), 1, 3, street, street);
    }
    if (!found) GTEST_SKIP() << "../shared/data/blender-street* not present (a user's clone)";
}

/// svgf.json as expanded, with A-Trous iterations `keep` and beyond cut out of every chain, the
/// last kept iteration feeding what the cut ones fed, and the colour history resampled
/// bilinearly: the chains svgf-fast.json's parameters ask for, made by editing the graph.
GraphDesc withIterationsCut(int keep) {
    GraphDesc g = loadGraphFile(shipped("svgf.json"));
    const std::regex iteration(R"(^(\w+)\.atrous(\d)$)");
    auto cut = [&](const std::string& pass) {
        std::smatch m;
        return std::regex_match(pass, m, iteration) && std::stoi(m[2]) >= keep;
    };
    std::erase_if(g.passes, [&](const PassNode& p) { return cut(p.name); });
    for (auto& p : g.passes)
        if (p.type == "Reprojection" && p.name.ends_with(".reprojection")) {
            json params = json::parse(p.paramsJson);
            params["filter"] = "bilinear";
            p.paramsJson = params.dump();
        }
    std::erase_if(g.edges, [&](const EdgeDesc& e) { return cut(e.toPass); });
    for (auto& e : g.edges)
        if (cut(e.fromPass))
            e.fromPass =
                e.fromPass.substr(0, e.fromPass.find('.')) + ".atrous" + std::to_string(keep - 1);
    return g;
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
// exactly iterations 0 and 1 of its chain, bit-identical to svgf.json with 2-4 cut out.
TEST(ShippedGroups, IterationsParameterRunsExactlyThatManyIterations) {
    const std::string input = builtInRoom();
    const Outputs fast = run(shipped("svgf-fast.json"), input, 1, 4);
    const Outputs expected = run(withIterationsCut(2), input, 1, 4);
    const Outputs full = run(shipped("svgf.json"), input, 1, 4);
    ASSERT_TRUE(expected.error.empty()) << expected.error;
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
