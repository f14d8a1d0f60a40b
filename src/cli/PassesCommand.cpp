#include <iostream>
#include <nlohmann/json.hpp>

#include "Commands.h"
#include "Common.h"

namespace kestrel::cli {

namespace {

std::string valueText(const ParamValue& v) { return paramValueToString(v); }

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
    return {{"type", t.desc.type}, {"description", t.desc.description}, {"sink", t.desc.sink},
            {"module", t.module},  {"ports", ports},                    {"params", params}};
}

void printText(const PassType& t) {
    std::cout << t.desc.type << "  " << t.desc.description << "\n";
    for (const auto& p : t.desc.ports) {
        std::string flags;
        if (p.history) flags = " (history)";
        else if (p.optional) flags = " (optional)";
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
            for (size_t i = 0; i < p.choices.size(); ++i) std::cout << (i ? "|" : "") << p.choices[i];
        }
        std::cout << "  " << p.description << "\n";
    }
    std::cout << "\n";
}

}  // namespace

void addPassesCommand(CLI::App& app, Action& action) {
    auto* cmd = app.add_subcommand("passes", "List every registered pass type: ports, formats, parameters");
    auto json = std::make_shared<bool>(false);
    cmd->add_flag("--json", *json, "Machine-readable output");
    cmd->callback([&action, json] {
        action = [json] {
            auto plugins = loadPlugins();
            if (*json) {
                nlohmann::json all = nlohmann::json::array();
                for (const auto* t : plugins->registry.all()) all.push_back(toJson(*t));
                std::cout << all.dump(2) << "\n";
            } else {
                for (const auto* t : plugins->registry.all()) printText(*t);
            }
            return 0;
        };
    });
}

}  // namespace kestrel::cli
