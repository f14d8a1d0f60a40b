#include <algorithm>
#include <filesystem>
#include <iostream>
#include <nlohmann/json.hpp>

#include "Commands.h"
#include "Common.h"

namespace kestrel::cli {

namespace {

std::string valueText(const ParamValue& v) {
    return paramValueToString(v);
}

nlohmann::json toJson(const PassType& t) {
    using nlohmann::json;
    json ports = json::array(), params = json::array();
    for (const auto& p : t.desc.ports)
        ports.push_back({{"name", p.name},
                         {"kind", p.kind == PortKind::Input ? "input" : "output"},
                         {"format", std::string(formatName(p.format))},
                         {"optional", p.optional},
                         {"history", p.history},
                         {"description", p.description}});
    for (const auto& p : t.desc.params) {
        json j = {{"name", p.name},
                  {"type", std::string(paramTypeName(p.type))},
                  {"default", std::visit([](const auto& x) { return json(x); }, p.defaultValue)},
                  {"description", p.description}};
        if (p.type == ParamType::Int || p.type == ParamType::Float) j["range"] = {p.min, p.max};
        if (p.type == ParamType::Enum) j["choices"] = p.choices;
        params.push_back(j);
    }
    return {{"type", t.desc.type}, {"description", t.desc.description},
            {"sink", t.desc.sink}, {"module", t.module},
            {"ports", ports},      {"params", params}};
}

void printText(const PassType& t) {
    std::cout << t.desc.type << "  " << t.desc.description << "\n";
    for (const auto& p : t.desc.ports) {
        std::string flags;
        if (p.history)
            flags = " (history)";
        else if (p.optional)
            flags = " (optional)";
        std::cout << "    " << (p.kind == PortKind::Input ? "in  " : "out ") << p.name << ": "
                  << formatName(p.format) << flags << "  " << p.description << "\n";
    }
    for (const auto& p : t.desc.params) {
        std::cout << "    param " << p.name << ": " << paramTypeName(p.type) << " = "
                  << valueText(p.defaultValue);
        if (p.type == ParamType::Int || p.type == ParamType::Float)
            std::cout << " in [" << p.min << ", " << p.max << "]";
        if (p.type == ParamType::Enum) {
            std::cout << " of ";
            for (size_t i = 0; i < p.choices.size(); ++i)
                std::cout << (i ? "|" : "") << p.choices[i];
        }
        std::cout << "  " << p.description << "\n";
    }
    std::cout << "\n";
}

/// Every group defined in a .json file under `dir` (recursively), sorted by file then name.
std::vector<GroupInfo> groupsIn(const std::filesystem::path& dir) {
    namespace fs = std::filesystem;
    std::vector<fs::path> files;
    std::error_code ec;
    if (!fs::is_directory(dir, ec))
        throw Error("graph folder " + dir.string() + " is not a folder");
    for (fs::recursive_directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec))
        if (it->is_regular_file() && it->path().extension() == ".json") files.push_back(it->path());
    std::sort(files.begin(), files.end());
    std::vector<GroupInfo> all;
    for (const auto& f : files) {
        auto groups = listGroups(f);
        all.insert(all.end(), groups.begin(), groups.end());
    }
    return all;
}

nlohmann::json toJson(const GroupInfo& g) {
    nlohmann::json params = nlohmann::json::object();
    for (const auto& [name, value] : g.params) params[name] = nlohmann::json::parse(value);
    return {{"group", g.name},      {"file", g.file},       {"description", g.comment},
            {"inputs", g.inputs},   {"outputs", g.outputs}, {"params", params},
            {"passes", g.passCount}};
}

void printText(const GroupInfo& g) {
    auto join = [](const std::vector<std::string>& v) {
        std::string s;
        for (const auto& x : v) s += (s.empty() ? "" : ", ") + x;
        return s.empty() ? std::string("none") : s;
    };
    std::cout << "group " << g.name << "  (" << g.file << ", " << g.passCount << " passes)  "
              << g.comment << "\n    inputs: " << join(g.inputs)
              << "\n    outputs: " << join(g.outputs) << "\n";
    for (const auto& [name, value] : g.params)
        std::cout << "    param " << name << " = " << value << "\n";
    std::cout << "\n";
}

}  // namespace

void addPassesCommand(CLI::App& app, Action& action) {
    auto* cmd =
        app.add_subcommand("passes", "List every registered pass type: ports, formats, parameters");
    auto json = std::make_shared<bool>(false);
    auto graphs = std::make_shared<std::string>();
    cmd->add_flag("--json", *json, "Machine-readable output");
    cmd->add_option("--graphs", *graphs,
                    "Also list the groups the graph files in this folder define (default: the "
                    "shipped graphs)");
    cmd->callback([&action, json, graphs] {
        action = [json, graphs]() -> int {
            auto plugins = loadPlugins();
            std::vector<GroupInfo> groups;
            if (int rc = exitTwoOnUsageError([&] {
                    groups = groupsIn(graphs->empty() ? shippedGraph("svgf.json").parent_path()
                                                      : std::filesystem::path(*graphs));
                    return 0;
                }))
                return rc;
            if (*json) {
                // One array: pass types (with "type") first, then groups (with "group").
                nlohmann::json all = nlohmann::json::array();
                for (const auto* t : plugins->registry.all()) all.push_back(toJson(*t));
                for (const auto& g : groups) all.push_back(toJson(g));
                std::cout << all.dump(2) << "\n";
            } else {
                for (const auto* t : plugins->registry.all()) printText(*t);
                for (const auto& g : groups) printText(g);
            }
            return 0;
        };
    });
}

}  // namespace kestrel::cli
