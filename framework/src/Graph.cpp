#include "kestrel/Graph.h"

#include <fnmatch.h>

#include <cstdint>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>

#include "GraphInternal.h"
#include "kestrel/InputFiles.h"

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

/// Sets `param` on every pass `target` names or matches; true if any.
bool overridePasses(GraphDesc& graph, const std::string& target, const std::string& param,
                    const json& value, bool pattern) {
    bool found = false;
    for (auto& p : graph.passes)
        if (pattern ? fnmatch(target.c_str(), p.name.c_str(), 0) == 0 : p.name == target) {
            json params = json::parse(p.paramsJson);
            params[param] = value;
            p.paramsJson = params.dump();
            found = true;
        }
    return found;
}

/// Sets group parameter `param` of every instance `target` names or matches: every inner
/// parameter bound to it; true if any instance has that group parameter.
bool overrideInstances(GraphDesc& graph, const std::string& target, const std::string& param,
                       const json& value, bool pattern) {
    bool found = false;
    for (const auto& inst : graph.instances) {
        if (!(pattern ? fnmatch(target.c_str(), inst.path.c_str(), 0) == 0 : inst.path == target))
            continue;
        auto it = inst.bindings.find(param);
        if (it == inst.bindings.end()) continue;
        found = true;
        for (const auto& [pass, inner] : it->second)
            overridePasses(graph, pass, inner, value, false);
    }
    return found;
}

}  // namespace

void applyOverride(GraphDesc& graph, const std::string& assignment) {
    auto eq = assignment.find('=');
    auto dot = eq == std::string::npos ? std::string::npos : assignment.rfind('.', eq);
    if (eq == std::string::npos || dot == std::string::npos || dot == 0 || dot + 1 == eq)
        throw Error("--set " + assignment + ": expected pass.param=value");
    std::string pass = assignment.substr(0, dot);
    std::string param = assignment.substr(dot + 1, eq - dot - 1);
    std::string text = assignment.substr(eq + 1);
    json value;
    checkJsonText(text, "--set " + pass + "." + param);
    try {
        value = json::parse(text);
    } catch (const json::parse_error&) {
        value = text;  // not JSON: a plain string
    } catch (const json::exception& e) {
        // A number beyond a double (1e999) is JSON the parser refuses: the graph file's message,
        // naming the assignment instead of a file.
        throw Error("--set " + assignment + ": " + jsonProblem(e));
    }
    // A pattern (*, ?, [..]) sets the parameter on every pass whose name matches: e.g.
    // '*atrous*.exact=true' for all A-Trous iterations of every chain. A group instance's
    // parameter (diffuse.sigmaL) goes to every inner parameter bound to it; a pattern that
    // matches instances with that group parameter ('*.sigmaL') sets it on them only, not on
    // every pass the pattern also matches.
    const bool pattern = pass.find_first_of("*?[") != std::string::npos;
    if (overrideInstances(graph, pass, param, value, pattern)) return;
    if (overridePasses(graph, pass, param, value, pattern)) return;
    std::string known, groupParams;
    for (const auto& p : graph.passes) known += (known.empty() ? "" : ", ") + p.name;
    for (const auto& i : graph.instances)
        for (const auto& [name, targets] : i.bindings)
            groupParams += (groupParams.empty() ? "" : ", ") + i.path + "." + name;
    if (!groupParams.empty()) known += "; group parameters: " + groupParams;
    throw Error("--set " + assignment + ": no pass " + (pattern ? "matches '" : "named '") + pass +
                "' (passes: " + known + ")");
}

}  // namespace kestrel
