#include "kestrel/Graph.h"

#include <fnmatch.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>

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

bool splitPassPort(const std::string& s, std::string& pass, std::string& port) {
    auto dot = s.find('.');
    if (dot == std::string::npos || dot == 0 || dot + 1 == s.size()) return false;
    if (s.find('.', dot + 1) != std::string::npos) return false;
    pass = s.substr(0, dot);
    port = s.substr(dot + 1);
    return true;
}

void checkKeys(const json& obj, const std::set<std::string>& allowed, const std::string& path,
               std::vector<Diagnostic>& diags) {
    for (const auto& [k, v] : obj.items())
        if (!allowed.count(k)) {
            std::string list;
            for (const auto& a : allowed) list += (list.empty() ? "" : ", ") + a;
            diags.push_back(
                {path + "." + k, "unknown key '" + k + "' (expected one of: " + list + ")"});
        }
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

}  // namespace

GraphDesc parseGraph(const std::string& text, const std::filesystem::path& source) {
    const std::string where = source.empty() ? std::string("graph") : source.string();
    json doc;
    try {
        doc = json::parse(text);
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
    GraphDesc g;
    g.sourcePath = source;
    std::vector<Diagnostic> diags;
    if (!doc.is_object())
        throw GraphError(std::vector<Diagnostic>{{"", "expected a JSON object at the top level"}});
    checkKeys(doc, {"kestrel", "name", "comment", "passes", "edges", "outputs"}, "", diags);
    for (auto& d : diags) d.path = d.path.substr(1);

    if (!doc.contains("kestrel"))
        diags.push_back({"kestrel", "missing graph format version (expected \"kestrel\": " +
                                        std::to_string(kGraphFormatVersion) + ")"});
    else if (!doc["kestrel"].is_number_integer() ||
             doc["kestrel"].get<int>() != kGraphFormatVersion)
        diags.push_back({"kestrel", "unsupported graph format version " + doc["kestrel"].dump() +
                                        " (this kestrel reads version " +
                                        std::to_string(kGraphFormatVersion) + ")"});
    if (doc.contains("name")) {
        if (doc["name"].is_string())
            g.name = doc["name"];
        else
            diags.push_back({"name", "expected string, got " + doc["name"].dump()});
    }
    if (g.name.empty()) g.name = source.empty() ? "graph" : source.stem().string();
    if (doc.contains("comment") && doc["comment"].is_string()) g.comment = doc["comment"];

    std::set<std::string> names;
    if (!doc.contains("passes") || !doc["passes"].is_array()) {
        diags.push_back({"passes", "expected an array of passes"});
    } else {
        const auto& passes = doc["passes"];
        for (size_t i = 0; i < passes.size(); ++i) {
            std::string p = "passes[" + std::to_string(i) + "]";
            const auto& jp = passes[i];
            if (!jp.is_object()) {
                diags.push_back({p, "expected an object with name and type"});
                continue;
            }
            checkKeys(jp, {"name", "type", "params", "comment"}, p, diags);
            PassNode n;
            if (!jp.contains("name") || !jp["name"].is_string() ||
                jp["name"].get<std::string>().empty())
                diags.push_back({p + ".name", "expected a non-empty string"});
            else
                n.name = jp["name"];
            if (n.name.find('.') != std::string::npos)
                diags.push_back({p + ".name", "pass name '" + n.name + "' must not contain '.'"});
            if (!jp.contains("type") || !jp["type"].is_string())
                diags.push_back({p + ".type", "expected a pass type name (string)"});
            else
                n.type = jp["type"];
            if (jp.contains("params")) {
                if (!jp["params"].is_object())
                    diags.push_back(
                        {p + ".params", "expected an object, got " + jp["params"].dump()});
                else
                    n.paramsJson = jp["params"].dump();
            }
            if (jp.contains("comment") && jp["comment"].is_string()) n.comment = jp["comment"];
            if (!n.name.empty() && !names.insert(n.name).second)
                diags.push_back({p + ".name", "duplicate pass name '" + n.name + "'"});
            g.passes.push_back(std::move(n));
        }
    }
    if (doc.contains("edges")) {
        const auto& edges = doc["edges"];
        if (!edges.is_array())
            diags.push_back({"edges", "expected an array of edges"});
        else
            for (size_t i = 0; i < edges.size(); ++i) {
                std::string p = "edges[" + std::to_string(i) + "]";
                const auto& je = edges[i];
                if (!je.is_object()) {
                    diags.push_back({p, "expected an object with from and to"});
                    g.edges.push_back({});
                    continue;
                }
                checkKeys(je, {"from", "to", "history", "comment"}, p, diags);
                EdgeDesc e;
                for (const char* key : {"from", "to"}) {
                    std::string pass, port;
                    if (!je.contains(key) || !je[key].is_string() ||
                        !splitPassPort(je[key].get<std::string>(), pass, port)) {
                        diags.push_back(
                            {p + "." + key, std::string("expected \"pass.port\", got ") +
                                                (je.contains(key) ? je[key].dump() : "nothing")});
                        continue;
                    }
                    if (std::string(key) == "from")
                        e.fromPass = pass, e.fromPort = port;
                    else
                        e.toPass = pass, e.toPort = port;
                }
                if (je.contains("history")) {
                    if (!je["history"].is_boolean())
                        diags.push_back({p + ".history",
                                         "expected true or false, got " + je["history"].dump()});
                    else
                        e.history = je["history"];
                }
                g.edges.push_back(std::move(e));
            }
    }
    if (doc.contains("outputs")) {
        const auto& outs = doc["outputs"];
        if (!outs.is_array())
            diags.push_back({"outputs", "expected an array of \"pass.port\" strings"});
        else
            for (size_t i = 0; i < outs.size(); ++i) {
                if (!outs[i].is_string() || outs[i].get<std::string>().empty())
                    diags.push_back({"outputs[" + std::to_string(i) + "]",
                                     "expected \"pass.port\" or \"pass\""});
                else
                    g.outputs.push_back(outs[i]);
            }
    }
    if (!diags.empty()) throw GraphError(std::move(diags));
    return g;
}

namespace {
// A graph is a few kilobytes; anything far larger is the wrong file (a frame, /dev/urandom).
constexpr std::uintmax_t kMaxGraphBytes = 16u << 20;

/// Refuses what cannot be a graph before reading it: a device or pipe would be read forever.
void checkGraphFile(const std::filesystem::path& path) {
    namespace fs = std::filesystem;
    std::error_code ec;
    const fs::file_status st = fs::status(path, ec);
    if (ec || !fs::exists(st))
        throw Error("cannot read graph file " + path.string() + ": " +
                    (ec ? ec.message() : std::string("no such file")));
    if (fs::is_directory(st))
        throw Error("graph file " + path.string() + " is a directory (expected a .json file)");
    if (!fs::is_regular_file(st))
        throw Error("graph file " + path.string() +
                    " is not a regular file (a device, pipe or socket); expected a .json file");
    const std::uintmax_t size = fs::file_size(path, ec);
    if (!ec && size > kMaxGraphBytes)
        throw Error("graph file " + path.string() + " is " + std::to_string(size) +
                    " bytes; a graph is at most 16 MiB (is it the right file?)");
}
}  // namespace

GraphDesc loadGraphFile(const std::filesystem::path& path) {
    checkGraphFile(path);
    std::ifstream in(path, std::ios::binary);
    if (!in) throw Error("cannot read graph file " + path.string());
    // Read at most one byte past the limit: the file may have grown since it was checked.
    std::string text(kMaxGraphBytes + 1, '\0');
    in.read(text.data(), std::streamsize(text.size()));
    text.resize(size_t(in.gcount()));
    if (text.size() > kMaxGraphBytes)
        throw Error("graph file " + path.string() +
                    " is larger than 16 MiB (is it the right file?)");
    return parseGraph(text, path);
}

void applyOverride(GraphDesc& graph, const std::string& assignment) {
    auto eq = assignment.find('=');
    auto dot = assignment.find('.');
    if (eq == std::string::npos || dot == std::string::npos || dot > eq || dot == 0 ||
        dot + 1 == eq)
        throw Error("--set " + assignment + ": expected pass.param=value");
    std::string pass = assignment.substr(0, dot);
    std::string param = assignment.substr(dot + 1, eq - dot - 1);
    std::string text = assignment.substr(eq + 1);
    json value;
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
    // '*atrous*.exact=true' for all A-Trous iterations of every chain.
    const bool pattern = pass.find_first_of("*?[") != std::string::npos;
    bool found = false;
    for (auto& p : graph.passes)
        if (pattern ? fnmatch(pass.c_str(), p.name.c_str(), 0) == 0 : p.name == pass) {
            json params = json::parse(p.paramsJson);
            params[param] = value;
            p.paramsJson = params.dump();
            found = true;
            if (!pattern) return;
        }
    if (found) return;
    std::string known;
    for (const auto& p : graph.passes) known += (known.empty() ? "" : ", ") + p.name;
    throw Error("--set " + assignment + ": no pass " + (pattern ? "matches '" : "named '") + pass +
                "' (passes: " + known + ")");
}

}  // namespace kestrel
