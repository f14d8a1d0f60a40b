#include "Dump.h"

#include <fnmatch.h>

#include <algorithm>
#include <nlohmann/json.hpp>

#include "kestrel/Error.h"

namespace kestrel::cli {

namespace fs = std::filesystem;

std::vector<std::string> computedResources(const CompiledGraph& compiled) {
    std::vector<std::string> live;
    for (const auto& r : compiled.resources())
        if (std::find(live.begin(), live.end(), r.producer) == live.end())
            live.push_back(r.producer);
    return live;
}

std::vector<std::string> matchResources(const CompiledGraph& compiled, const std::string& pattern) {
    std::vector<std::string> matched;
    for (const auto& name : computedResources(compiled))
        if (fnmatch(pattern.c_str(), name.c_str(), 0) == 0) matched.push_back(name);
    return matched;
}

std::vector<std::string> matchDumps(const CompiledGraph& compiled,
                                    const std::vector<std::string>& patterns) {
    std::vector<std::string> matched;
    for (const auto& pattern : patterns) {
        const auto names = matchResources(compiled, pattern);
        if (names.empty()) {
            std::string list;
            for (const auto& n : computedResources(compiled))
                list += (list.empty() ? "" : ", ") + n;
            throw Error("--dump '" + pattern + "' matches no resource this graph computes for " +
                        "this scene (it computes: " + list + ")");
        }
        for (const auto& name : names)
            if (std::find(matched.begin(), matched.end(), name) == matched.end())
                matched.push_back(name);
    }
    return matched;
}

void addDumpWriters(GraphDesc& graph, const std::vector<std::string>& resources,
                    const fs::path& dir) {
    for (const auto& r : resources) {
        const auto dot = r.rfind('.');  // instance paths contain dots: diffuse.atrous0.color
        std::string name = "dump_" + r;
        std::replace_if(
            name.begin(), name.end(), [](char c) { return !std::isalnum((unsigned char)c); }, '_');
        PassNode writer;
        writer.name = name;
        writer.type = "ExrWriter";
        writer.paramsJson = nlohmann::json{
            {"path", (dir / (r + ".####.exr")).string()},
            {"pixelType",
             "float"}}.dump();
        writer.comment = "--dump " + r;
        graph.passes.push_back(writer);
        graph.edges.push_back({r.substr(0, dot), r.substr(dot + 1), name, "color", false});
    }
}

fs::path defaultDumpDir(const GraphDesc& graph, const Registry& registry) {
    for (const auto& n : graph.passes) {
        const PassType* t = registry.find(n.type);
        if (!t || !t->desc.sink) continue;
        const auto params = nlohmann::json::parse(n.paramsJson);
        if (params.contains("path") && params["path"].is_string())
            return fs::path(params["path"].get<std::string>()).parent_path() / "dump";
    }
    return "dump";
}

}  // namespace kestrel::cli
