#include "Common.h"

#include <spdlog/sinks/stdout_color_sinks.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <iostream>
#include <map>
#include <nlohmann/json.hpp>

#include "DefaultScene.h"
#include "kestrel/FramePattern.h"
#include "kestrel/Log.h"

namespace kestrel::cli {

namespace fs = std::filesystem;
bool gVerbose = false;

void setupLogging(bool verbose) {
    gVerbose = verbose;
    auto logger = spdlog::stderr_color_mt("kestrel");
    logger->set_pattern("%^%l%$: %v");
    spdlog::set_default_logger(logger);
    spdlog::set_level(verbose ? spdlog::level::debug : spdlog::level::info);
}

std::unique_ptr<Plugins> loadPlugins() {
    auto p = std::make_unique<Plugins>();
    p->loader.loadDirectories(defaultPluginDirectories(), p->registry);
    if (p->registry.all().empty())
        spdlog::warn(
            "no pass plugins found (looked in the install's plugin directory and "
            "KESTREL_PLUGIN_PATH)");
    return p;
}

namespace {
using graphpaths::isSink;
using graphpaths::pathParam;

fs::path exeDir() {
    std::error_code ec;
    return fs::read_symlink("/proc/self/exe", ec).parent_path();
}
}  // namespace

fs::path shippedGraph(const std::string& name) {
    fs::path installed = exeDir() / ".." / KESTREL_INSTALL_GRAPH_DIR / name;
    std::error_code ec;
    if (fs::exists(installed, ec)) return fs::weakly_canonical(installed, ec);
    return fs::path(KESTREL_SOURCE_GRAPH_DIR) / name;
}

namespace {
void keepPassesOnWriters(GraphDesc& g, const Registry& reg) {
    for (const auto& n : std::vector<PassNode>(g.passes))
        if (const PassType* t = reg.find(n.type);
            t && isSink(*t) && t->desc.findParam("keepPasses"))
            applyOverride(g, n.name + ".keepPasses=true", &reg);
}
}  // namespace

GraphDesc prepareGraph(const GraphOptions& o, const Registry& reg) {
    fs::path path = o.graph.empty() ? shippedGraph("svgf.json") : fs::path(o.graph);
    GraphDesc g = loadGraphFile(path);
    graphpaths::assignInputs(g, reg, o.inputs);
    graphpaths::assignOutputs(g, reg, o.outputs);
    if (o.keepPasses) keepPassesOnWriters(g, reg);  // before --set, which may turn one off
    for (const auto& s : o.sets) applyOverride(g, s, &reg);
    for (const auto& n : g.passes) {
        const PassType* t = reg.find(n.type);
        if (!t || !pathParam(n).empty()) continue;
        if (isSource(*t)) {
            fs::path scene = ensureDefaultScene(fs::path(o.outDir) / "default-scene");
            applyOverride(g,
                          n.name + ".path=" +
                              nlohmann::json((scene / "noisy" / "frame_####.exr").string()).dump());
            spdlog::info("{}: no --input given; using the built-in scene in {}", n.name,
                         scene.string());
        } else if (isSink(*t)) {
            fs::path out = fs::path(o.outDir) / g.name / (n.name + ".####.exr");
            applyOverride(g, n.name + ".path=" + nlohmann::json(out.string()).dump());
            if (t->desc.findParam("preview")) {
                fs::path png = fs::path(o.outDir) / g.name / (n.name + ".####.png");
                applyOverride(g, n.name + ".preview=" + nlohmann::json(png.string()).dump());
            }
            spdlog::info("{}: no --output given; writing {}", n.name, out.string());
        }
    }
    return g;
}

void printGraphError(const GraphError& e, const GraphDesc* graph) {
    // The compiler names the pass (and parameter) of each finding itself: "passes[1].params.alpha
    // (taa.alpha): ...", or for a pass inside a group instance the JSON path in the definition.
    (void)graph;
    for (const auto& d : e.diagnostics()) std::cerr << "error: " << d.str() << "\n";
}

void refuseUnusedOverrides(const CompiledGraph& compiled, const std::vector<std::string>& sets,
                           const Registry& registry, const std::string& option) {
    if (auto unused = unusedOverrides(compiled, sets, registry, option); !unused.empty())
        throw GraphError(std::move(unused));
}

int exitTwoOnUsageError(const std::function<int()>& fn) {
    try {
        return fn();
    } catch (const GraphError& e) {
        printGraphError(e);
        return 2;
    } catch (const Error& e) {
        std::cerr << "error: " << e.what() << "\n";
        return 2;
    }
}

std::string markSinkInput(GraphDesc& g, const Registry& reg, bool detach) {
    std::map<std::string, std::string> sinks;  // writer -> its first required input (its image)
    for (const auto& p : g.passes)
        if (const PassType* t = reg.find(p.type); t && t->desc.sink) {
            std::string& image = sinks[p.name];
            for (const auto& port : t->desc.ports)
                if (port.kind == PortKind::Input && !port.optional) {
                    image = port.name;
                    break;
                }
        }
    auto isSinkName = [&](const std::string& n) { return sinks.count(n) > 0; };
    // The edge into the first writer's image, not one into an optional input such as its alpha
    // (a graph that extends another may list that edge first); for writers with optional inputs
    // only, the first edge into one.
    std::string marked, fallback;
    for (const auto& e : g.edges)
        if (isSinkName(e.toPass)) {
            if (marked.empty() && sinks[e.toPass] == e.toPort)
                marked = e.fromPass + "." + e.fromPort;
            if (fallback.empty()) fallback = e.fromPass + "." + e.fromPort;
        }
    if (marked.empty()) marked = fallback;
    if (marked.empty())
        throw Error("graph '" + g.name + "' has no writer whose input could be measured");
    if (detach) {
        std::erase_if(g.edges, [&](const EdgeDesc& e) { return isSinkName(e.toPass); });
        std::erase_if(g.passes, [&](const PassNode& p) { return isSinkName(p.name); });
    }
    if (std::find(g.outputs.begin(), g.outputs.end(), marked) == g.outputs.end())
        g.outputs.push_back(marked);
    return marked;
}

namespace {
/// "1-12", "1-4, 7, 9-12": frame numbers as runs.
std::string frameRuns(const std::vector<int64_t>& frames) {
    std::string s;
    for (size_t i = 0; i < frames.size();) {
        size_t j = i;
        while (j + 1 < frames.size() && frames[j + 1] == frames[j] + 1) ++j;
        s += (s.empty() ? "" : ", ") + std::to_string(frames[i]) +
             (j > i ? "-" + std::to_string(frames[j]) : "");
        i = j + 1;
    }
    return s;
}
}  // namespace

void checkFramesExist(const std::vector<int64_t>& asked, std::vector<int64_t> available,
                      const std::string& option, const std::string& input,
                      const std::string& remedy) {
    if (asked.empty() || available.empty()) return;
    std::sort(available.begin(), available.end());
    // Only frames outside the sequence: a gap inside it (a frame lost, or still being written
    // by the renderer) stays a runtime error of that frame, after the frames before it.
    std::vector<int64_t> missing;
    for (auto f : asked)
        if (f < available.front() || f > available.back()) missing.push_back(f);
    if (missing.empty()) return;
    std::sort(missing.begin(), missing.end());
    missing.erase(std::unique(missing.begin(), missing.end()), missing.end());
    throw Error(option + ": frame" + (missing.size() > 1 ? "s " : " ") + frameRuns(missing) +
                (missing.size() > 1 ? " are" : " is") + " not in the input " + input +
                " (it has frames " + frameRuns(available) + "); " + remedy);
}

std::vector<int64_t> parseFrameList(const std::string& text) {
    try {
        return parseFrameRange(text);
    } catch (const Error& e) {
        throw Error(std::string("--frames: ") + e.what());
    }
}

}  // namespace kestrel::cli
