#include "kestrel/Graph.h"

#include <fnmatch.h>

#include <algorithm>
#include <array>
#include <cstdint>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>

#include "GraphInternal.h"
#include "kestrel/InputFiles.h"
#include "ParamCheck.h"
#include "kestrel/Registry.h"

namespace kestrel {

using nlohmann::json;

namespace {

/// Line and column (1-based) of a byte offset in text.
std::pair<size_t, size_t> lineColumn(const std::string& text, size_t offset) {
    size_t line = 1, col = 1;
    for (size_t i = 0; i < offset && i < text.size(); ++i) {
        if (text[i] == '\n')
            ++line, col = 1;
        else
            ++col;
    }
    return {line, col};
}

/// nlohmann's message without its "[json.exception.out_of_range.406] " tag, with the reason
/// for a number overflow ("number overflow parsing '1e999'" alone does not say what the limit is).
std::string jsonProblem(const json::exception& e) {
    std::string msg = e.what();
    if (auto close = msg.find("] "); msg.rfind("[json.exception.", 0) == 0 && close != msg.npos)
        msg = msg.substr(close + 2);
    if (msg.find("number overflow") != std::string::npos)
        msg += " (beyond the largest double, about 1.8e308)";
    return msg;
}

// A graph is a few kilobytes; anything far larger is the wrong file (a frame, /dev/urandom).
constexpr std::uintmax_t kMaxGraphBytes = 16u << 20;

/// Refuses what cannot be a graph before reading it: a device or pipe would be read forever.
void checkGraphFile(const std::filesystem::path& path) {
    checkRegularFile(path, "graph file", "a .json file");
    std::error_code ec;
    const std::uintmax_t size = std::filesystem::file_size(path, ec);
    if (!ec && size > kMaxGraphBytes)
        throw Error("graph file " + path.string() + " is " + std::to_string(size) +
                    " bytes; a graph is at most 16 MiB (is it the right file?)");
}

}  // namespace

namespace detail {

json parseJsonText(const std::string& text, const std::string& where) {
    checkJsonText(text, where);  // before anything recursive walks the document
    try {
        return json::parse(text);
    } catch (const json::parse_error& e) {
        auto [line, col] = lineColumn(text, e.byte == 0 ? 0 : e.byte - 1);
        std::string msg = e.what();
        // nlohmann's message: "[json.exception.parse_error.101] parse error at line 1, column 2:
        // syntax error while parsing value - ..." — keep the part after "syntax error".
        auto pos = msg.find("syntax error");
        std::string detail = pos == std::string::npos ? msg : msg.substr(pos);
        throw GraphError(
            std::vector<Diagnostic>{{"", where + ":" + std::to_string(line) + ":" +
                                             std::to_string(col) + ": JSON " + detail}});
    } catch (const json::exception& e) {
        // Other parser errors (e.g. out_of_range.406 "number overflow parsing '1e400'") must be
        // a GraphError too, not escape to the caller (found by fuzz/graph_fuzzer seed errors.json).
        throw GraphError(std::vector<Diagnostic>{{"", where + ": JSON " + jsonProblem(e)}});
    }
}

std::string readGraphText(const std::filesystem::path& path) {
    checkGraphFile(path);
    return readRegularFile(path, "graph file", kMaxGraphBytes, "a .json file");
}

void checkKeys(const json& obj, const std::set<std::string>& allowed, const std::string& path,
               std::vector<Diagnostic>& diags) {
    for (const auto& [k, v] : obj.items())
        if (!allowed.count(k)) {
            std::string list;
            for (const auto& a : allowed) list += (list.empty() ? "" : ", ") + a;
            diags.push_back({(path.empty() ? "" : path + ".") + k,
                             "unknown key '" + k + "' (expected one of: " + list + ")"});
        }
}

void checkVersion(const json& doc, const std::string& prefix, std::vector<Diagnostic>& diags) {
    if (!doc.contains("kestrel"))
        diags.push_back(
            {prefix + "kestrel", "missing graph format version (expected \"kestrel\": " +
                                     std::to_string(kGraphFormatVersion) + ")"});
    else if (!doc["kestrel"].is_number_integer() ||
             doc["kestrel"].get<int>() != kGraphFormatVersion)
        diags.push_back({prefix + "kestrel", "unsupported graph format version " +
                                                 doc["kestrel"].dump() +
                                                 " (this kestrel reads version " +
                                                 std::to_string(kGraphFormatVersion) + ")"});
}

}  // namespace detail

bool splitPassPort(const std::string& s, std::string& pass, std::string& port) {
    auto dot = s.rfind('.');
    if (dot == std::string::npos || dot == 0 || dot + 1 == s.size()) return false;
    if (s[dot - 1] == '.' || s.front() == '.') return false;  // "a..b", ".a.b"
    pass = s.substr(0, dot);
    port = s.substr(dot + 1);
    return true;
}

GraphDesc parseGraph(const std::string& text, const std::filesystem::path& source) {
    const std::string where = source.empty() ? std::string("graph") : source.string();
    json doc = detail::parseJsonText(text, where);
    GraphDesc g;
    g.sourcePath = source;
    std::vector<Diagnostic> diags;
    if (!doc.is_object())
        throw GraphError(std::vector<Diagnostic>{{"", "expected a JSON object at the top level"}});
    detail::checkKeys(doc,
                      {"kestrel", "name", "comment", "passes", "edges", "outputs", "groups",
                       "include", "extends", "drop"},
                      "", diags);
    detail::checkVersion(doc, "", diags);
    if (doc.contains("name")) {
        if (doc["name"].is_string())
            g.name = doc["name"];
        else
            diags.push_back({"name", "expected string, got " + doc["name"].dump()});
    }
    if (g.name.empty()) g.name = source.empty() ? "graph" : source.stem().string();
    if (doc.contains("comment") && doc["comment"].is_string()) g.comment = doc["comment"];
    detail::expandDocument(doc, source, g, diags);
    if (!diags.empty()) throw GraphError(std::move(diags));
    return g;
}

GraphDesc loadGraphFile(const std::filesystem::path& path) {
    return parseGraph(detail::readGraphText(path), path);
}

std::vector<GroupInfo> listGroups(const std::filesystem::path& file) {
    return detail::groupsOfFile(file);
}

namespace {

using Targets = std::vector<std::pair<std::string, std::string>>;

/// One parsed assignment: `target.param=value`, and how the user wrote it.
struct Assignment {
    std::string text;    ///< "--set diffuse.sigmaL=6": the option as typed
    std::string target;  ///< pass, instance or pattern
    std::string param;
    json value;
    bool pattern = false;
};

bool matches(const Assignment& a, const std::string& name) {
    return a.pattern ? fnmatch(a.target.c_str(), name.c_str(), 0) == 0 : name == a.target;
}

/// Does the pass's type declare `param`? Without a registry every pass is taken to.
bool declares(const PassNode& p, const std::string& param, const Registry* registry) {
    if (!registry) return true;
    const PassType* t = registry->find(p.type);
    // An unknown type is the compiler's to report.
    return !t || t->desc.findParam(param) != nullptr;
}

/// Sets one parameter and records the option it came from. Set on the pass itself (`direct`),
/// it no longer comes from the group parameter it was bound to.
void setParam(PassNode& p, const std::string& param, const json& value, const std::string& by,
              bool direct) {
    json params = json::parse(p.paramsJson);
    params[param] = value;
    p.paramsJson = params.dump();
    p.setBy[param] = by;
    if (direct) p.boundParams.erase(param);
}

/// The passes `a` names or matches whose type declares the parameter.
Targets passTargets(const GraphDesc& graph, const Assignment& a, const Registry* registry) {
    Targets t;
    for (const auto& p : graph.passes)
        if (matches(a, p.name) && declares(p, a.param, registry)) t.emplace_back(p.name, a.param);
    return t;
}

/// The inner parameters bound to group parameter `a.param` of every instance `a` names or
/// matches; throws Error when its type or range refuses the value.
Targets instanceTargets(const GraphDesc& graph, const Assignment& a) {
    Targets t;
    for (const auto& inst : graph.instances) {
        if (!matches(a, inst.path)) continue;
        auto it = inst.bindings.find(a.param);
        if (it == inst.bindings.end()) continue;
        if (auto spec = inst.specs.find(a.param); spec != inst.specs.end())
            if (auto bad = detail::checkGroupValue(spec->second, a.value); !bad.empty())
                throw Error(a.text + ": group parameter '" + a.param + "' of " + inst.path +
                            " (group " + inst.group + "): " + bad);
        t.insert(t.end(), it->second.begin(), it->second.end());
    }
    return t;
}

std::string joinNames(const std::vector<std::string>& v, size_t most = 12) {
    std::string s;
    for (size_t i = 0; i < v.size() && i < most; ++i) s += (i ? ", " : "") + v[i];
    if (v.size() > most) s += ", +" + std::to_string(v.size() - most);
    return s;
}

/// The parameter names `a`'s target could have: the group parameters of the instances and the
/// declared parameters of the passes it names or matches.
std::vector<std::string> paramsOfTarget(const GraphDesc& graph, const Assignment& a,
                                        const Registry* registry) {
    std::set<std::string> names;
    for (const auto& inst : graph.instances)
        if (matches(a, inst.path))
            for (const auto& [name, b] : inst.bindings) names.insert(name);
    if (registry)
        for (const auto& p : graph.passes)
            if (matches(a, p.name))
                if (const PassType* t = registry->find(p.type))
                    for (const auto& d : t->desc.params) names.insert(d.name);
    return {names.begin(), names.end()};
}

/// One line for an assignment that sets nothing: what was meant, if anything is near.
[[noreturn]] void refuse(const GraphDesc& graph, const Assignment& a, const Registry* registry) {
    const auto params = paramsOfTarget(graph, a, registry);
    if (!params.empty() ||
        (!a.pattern && std::any_of(graph.instances.begin(), graph.instances.end(),
                                   [&](auto& i) { return i.path == a.target; }))) {
        // The pass, instance or pattern exists: the parameter is wrong.
        const std::string near = detail::nearestName(a.param, params);
        const bool isInstance = std::any_of(graph.instances.begin(), graph.instances.end(),
                                            [&](auto& i) { return matches(a, i.path); });
        std::string what = "no pass or group instance matching '" + a.target + "' has a";
        if (!a.pattern) what = (isInstance ? "instance '" : "pass '") + a.target + "' has no";
        throw Error(a.text + ": " + what + " parameter '" + a.param + "'" +
                    (near.empty() ? " (parameters: " + joinNames(params, 40) + ")"
                                  : " (did you mean '" + a.target + "." + near + "'?)"));
    }
    // Nothing of that name: suggest the nearest pass or instance (a case or one-letter typo).
    std::vector<std::string> names;
    for (const auto& i : graph.instances) names.push_back(i.path);
    for (const auto& p : graph.passes) names.push_back(p.name);
    const std::string near = a.pattern ? "" : detail::nearestName(a.target, names);
    std::vector<std::string> top;  // passes outside instances, and the instances
    for (const auto& p : graph.passes)
        if (p.instance.empty()) top.push_back(p.name);
    for (const auto& i : graph.instances) top.push_back(i.path + ".*");
    throw Error(a.text + ": " +
                (a.pattern ? "no pass matches '" : "no pass or group instance named '") + a.target +
                "'" +
                (near.empty() ? " (passes: " + joinNames(top, 40) + ")"
                              : " (did you mean '" + near + "." + a.param + "'?)"));
}

}  // namespace

Targets applyOverride(GraphDesc& graph, const std::string& assignment, const Registry* registry,
                      const std::string& option) {
    Assignment a;
    a.text = option + " " + assignment;
    auto eq = assignment.find('=');
    auto dot = eq == std::string::npos ? std::string::npos : assignment.rfind('.', eq);
    if (eq == std::string::npos || dot == std::string::npos || dot == 0 || dot + 1 == eq)
        throw Error(a.text + ": expected pass.param=value");
    a.target = assignment.substr(0, dot);
    a.param = assignment.substr(dot + 1, eq - dot - 1);
    const std::string text = assignment.substr(eq + 1);
    checkJsonText(text, a.text);
    try {
        a.value = json::parse(text);
    } catch (const json::parse_error&) {
        a.value = text;  // not JSON: a plain string
    } catch (const json::exception& e) {
        // A number beyond a double (1e999) is JSON the parser refuses: the graph file's message,
        // naming the assignment instead of a file.
        throw Error(a.text + ": " + jsonProblem(e));
    }
    // A pattern (*, ?, [..]) sets the parameter on every pass whose name matches: e.g.
    // '*atrous*.exact=true' for all A-Trous iterations of every chain. A group instance's
    // parameter (diffuse.sigmaL) goes to every inner parameter bound to it; a pattern that
    // matches instances with that group parameter ('*.sigmaL') sets it on them only, not on
    // every pass the pattern also matches.
    a.pattern = a.target.find_first_of("*?[") != std::string::npos;
    Targets targets = instanceTargets(graph, a);
    const bool direct = targets.empty();
    if (direct) targets = passTargets(graph, a, registry);
    if (targets.empty()) refuse(graph, a, registry);
    for (auto& p : graph.passes)
        for (const auto& [pass, param] : targets)
            if (p.name == pass) setParam(p, param, a.value, a.text, direct);
    return targets;
}

}  // namespace kestrel
