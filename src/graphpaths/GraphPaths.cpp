#include "graphpaths/GraphPaths.h"

#include <algorithm>
#include <nlohmann/json.hpp>

namespace kestrel::graphpaths {
namespace {

/// Applies "PATTERN" or "name=PATTERN" to the path of the matching pass.
void assignPaths(GraphDesc& g, const Registry& reg, const std::vector<std::string>& specs,
                 bool (*kind)(const PassType&), const char* flag) {
    std::vector<std::string> candidates;
    for (const auto& n : g.passes)
        if (const PassType* t = reg.find(n.type); t && kind(*t)) candidates.push_back(n.name);
    for (const auto& spec : specs) {
        std::string name, pattern = spec;
        auto eq = spec.find('=');
        if (eq != std::string::npos && eq > 0 && spec.find('/') > eq) {
            name = spec.substr(0, eq);
            pattern = spec.substr(eq + 1);
        } else {
            if (candidates.size() != 1) {
                std::string list;
                for (const auto& c : candidates) list += (list.empty() ? "" : ", ") + c;
                throw Error(std::string(flag) + " " + spec + ": the graph has " +
                            std::to_string(candidates.size()) + " such passes (" + list +
                            "); write " + flag + " name=PATTERN");
            }
            name = candidates.front();
        }
        if (std::find(candidates.begin(), candidates.end(), name) == candidates.end())
            throw Error(std::string(flag) + " " + spec + ": no " +
                        (std::string(flag) == "--input" ? "input" : "output") + " pass named '" +
                        name + "'");
        applyOverride(g, name + ".path=" + nlohmann::json(pattern).dump(), &reg, flag);
    }
}

}  // namespace

bool isSink(const PassType& t) {
    return t.desc.sink && t.desc.findParam("path") != nullptr;
}

std::string pathParam(const PassNode& n) {
    auto j = nlohmann::json::parse(n.paramsJson);
    if (j.contains("path") && j["path"].is_string()) return j["path"];
    return {};
}

bool isSourceType(const PassType& t) {
    for (const auto& p : t.desc.ports)
        if (p.kind == PortKind::Input) return false;
    return true;
}
bool isSource(const PassType& t) {
    return isSourceType(t) && t.desc.findParam("path") != nullptr;
}

void assignInputs(GraphDesc& g, const Registry& reg, const std::vector<std::string>& specs) {
    assignPaths(g, reg, specs, isSource, "--input");
}

void assignOutputs(GraphDesc& g, const Registry& reg, const std::vector<std::string>& specs) {
    assignPaths(g, reg, specs, isSink, "--output");
}

std::string sourcePath(const GraphDesc& g, const Registry& reg) {
    for (const auto& n : g.passes)
        if (const PassType* t = reg.find(n.type); t && isSource(*t) && !pathParam(n).empty())
            return pathParam(n);
    return {};
}

}  // namespace kestrel::graphpaths
