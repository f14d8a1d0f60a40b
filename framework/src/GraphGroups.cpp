// Includes and extends (docs/graphs.md): reads a graph document and the files it names into an
// Assembly and its group table, which GraphExpand.cpp turns into the flat GraphDesc. Every pass
// and edge keeps the JSON path it was written at (in its own file), so the compiler's messages
// point at the definition and name the instance path. Group parameters' types and ranges too.
#include <algorithm>
#include <cmath>
#include <deque>
#include <filesystem>
#include <map>
#include <nlohmann/json.hpp>
#include <set>
#include <string>
#include <vector>

#include "GraphAssembly.h"
#include "GraphInternal.h"
#include "ParamCheck.h"

namespace kestrel::detail {

namespace fs = std::filesystem;
using nlohmann::json;

std::string join(const std::vector<std::string>& v, const char* sep) {
    std::string s;
    for (const auto& x : v) s += (s.empty() ? "" : sep) + x;
    return s;
}

std::string firstComponent(const std::string& s) {
    return s.substr(0, s.find('.'));
}

std::string listOrNone(const std::vector<std::string>& v) {
    return v.empty() ? "none" : join(v);
}

std::vector<std::string> stringList(const json& obj, const char* key, const std::string& keyPath,
                                    std::vector<Diagnostic>& diags) {
    std::vector<std::string> r;
    if (!obj.contains(key)) return r;
    const json& a = obj[key];
    if (!a.is_array()) {
        diags.push_back({keyPath, "expected an array of names"});
        return r;
    }
    for (size_t i = 0; i < a.size(); ++i) {
        const std::string p = keyPath + "[" + std::to_string(i) + "]";
        if (!a[i].is_string() || a[i].get<std::string>().empty() ||
            a[i].get<std::string>().find('.') != std::string::npos)
            diags.push_back({p, "expected a non-empty name without '.', got " + a[i].dump()});
        else
            r.push_back(a[i]);
    }
    return r;
}

void parseEdge(const json& je, const std::string& p, std::vector<EdgeItem>& out,
               std::vector<Diagnostic>& diags_) {
    if (!je.is_object()) {
        diags_.push_back({p, "expected an object with from and to"});
        return;
    }
    checkKeys(je, {"from", "to", "history", "comment"}, p, diags_);
    EdgeItem e;
    e.origin = p;
    std::string pass, port;
    bool ok = true;
    if (!je.contains("from") || !je["from"].is_string() ||
        !splitPassPort(je["from"].get<std::string>(), pass, port)) {
        diags_.push_back({p + ".from", "expected \"pass.port\", got " +
                                           (je.contains("from") ? je["from"].dump() : "nothing")});
        ok = false;
    } else {
        e.from = je["from"];
    }
    const json* to = je.contains("to") ? &je["to"] : nullptr;
    e.toArray = to && to->is_array() && !to->empty();
    const size_t n = e.toArray ? to->size() : 1;
    for (size_t k = 0; k < n; ++k) {
        const json* t = e.toArray ? &(*to)[k] : to;
        const std::string tp = p + ".to" + (e.toArray ? "[" + std::to_string(k) + "]" : "");
        if (!t || !t->is_string() || !splitPassPort(t->get<std::string>(), pass, port)) {
            diags_.push_back({tp, "expected \"pass.port\" (or an array of them), got " +
                                      (t ? t->dump() : "nothing")});
            ok = false;
        } else {
            e.to.push_back(*t);
        }
    }
    if (je.contains("history")) {
        if (!je["history"].is_boolean()) {
            diags_.push_back(
                {p + ".history", "expected true or false, got " + je["history"].dump()});
            ok = false;
        } else {
            e.history = je["history"];
        }
    }
    if (ok) out.push_back(std::move(e));
}

namespace {

/// Files read through include and extends: their JSON, the groups they define, and the chain
/// of files being read (a file reached again while it is being read is a cycle).
class DocumentSet {
public:
    explicit DocumentSet(std::vector<Diagnostic>& diags) : diags_(diags) {}

    std::map<std::string, GroupDef> groups;
    std::vector<std::string> stack;  ///< display paths of the files being read
    std::vector<fs::path> files;     ///< every file included or extended
    std::vector<std::string> stackKeys;

    static std::string key(const fs::path& p) {
        std::error_code ec;
        fs::path c = fs::weakly_canonical(p, ec);
        return (ec ? p.lexically_normal() : c).string();
    }

    /// Reads `ref` (relative to `from`'s folder) as a JSON object; null after a diagnostic at
    /// `path`. `kind` is "include" or "extends", for the cycle message.
    const json* open(const std::string& ref, const fs::path& from, const std::string& path,
                     const char* kind, fs::path& file) {
        file = (from.empty() ? fs::path(ref) : from.parent_path() / ref).lexically_normal();
        const std::string k = key(file);
        if (auto it = std::find(stackKeys.begin(), stackKeys.end(), k); it != stackKeys.end()) {
            std::vector<std::string> cycle(stack.begin() + (it - stackKeys.begin()), stack.end());
            cycle.push_back(file.string());
            diags_.push_back({path, std::string(kind) + " cycle: " + join(cycle, " -> ")});
            return nullptr;
        }
        files.push_back(file);  // before reading: a file that fails to parse is still the user's
        try {
            docs_.push_back(parseJsonText(readGraphText(file), file.string()));
        } catch (const GraphError& e) {
            for (const auto& d : e.diagnostics()) diags_.push_back({path, d.str()});
            return nullptr;
        } catch (const Error& e) {
            diags_.push_back({path, e.what()});
            return nullptr;
        }
        if (!docs_.back().is_object()) {
            diags_.push_back({path, file.string() + ": expected a JSON object at the top level"});
            return nullptr;
        }
        return &docs_.back();
    }

    bool loaded(const fs::path& file) { return !loaded_.insert(key(file)).second; }
    void push(const fs::path& file) {
        stack.push_back(file.string());
        stackKeys.push_back(key(file));
    }
    void pop() {
        stack.pop_back();
        stackKeys.pop_back();
    }

private:
    std::vector<Diagnostic>& diags_;
    std::deque<json> docs_;  // a deque: pointers into it stay valid
    std::set<std::string> loaded_;
};

class Assembler {
public:
    Assembler(DocumentSet& docs, std::vector<Diagnostic>& diags) : docs_(docs), diags_(diags) {}

    /// `prefix` is "" for the main file, else "file: " (JSON paths in other files name them).
    Assembly assemble(const json& doc, const fs::path& file, const std::string& prefix) {
        Assembly a;
        if (doc.contains("extends")) a = extend(doc, file, prefix);
        includes(doc, file, prefix);
        collectGroups(doc, file, prefix);
        ownPasses(doc, prefix, a, doc.contains("extends"));
        if (doc.contains("edges")) {
            const json& edges = doc["edges"];
            if (!edges.is_array())
                diags_.push_back({prefix + "edges", "expected an array of edges"});
            else
                for (size_t i = 0; i < edges.size(); ++i)
                    parseEdge(edges[i], prefix + "edges[" + std::to_string(i) + "]", a.edges,
                              diags_);
        }
        if (doc.contains("outputs")) {
            const json& outs = doc["outputs"];
            if (!outs.is_array())
                diags_.push_back(
                    {prefix + "outputs", "expected an array of \"pass.port\" strings"});
            else
                for (size_t i = 0; i < outs.size(); ++i) {
                    const std::string p = prefix + "outputs[" + std::to_string(i) + "]";
                    if (!outs[i].is_string() || outs[i].get<std::string>().empty())
                        diags_.push_back({p, "expected \"pass.port\" or \"pass\""});
                    else
                        a.outputs.push_back({outs[i], p});
                }
        }
        return a;
    }

    /// Reads an include file's groups (and its own includes).
    void includes(const json& doc, const fs::path& file, const std::string& prefix) {
        if (!doc.contains("include")) return;
        const json& inc = doc["include"];
        if (!inc.is_array()) {
            diags_.push_back({prefix + "include", "expected an array of file names"});
            return;
        }
        for (size_t i = 0; i < inc.size(); ++i) {
            const std::string p = prefix + "include[" + std::to_string(i) + "]";
            if (!inc[i].is_string() || inc[i].get<std::string>().empty()) {
                diags_.push_back({p, "expected a file name (relative to this file)"});
                continue;
            }
            fs::path lib;
            const json* d = docs_.open(inc[i], file, p, "include", lib);
            if (!d || docs_.loaded(lib)) continue;  // included twice (a diamond): read once
            const std::string libPrefix = lib.string() + ": ";
            checkKeys(*d, {"kestrel", "comment", "groups", "include"}, lib.string() + ":", diags_);
            checkVersion(*d, libPrefix, diags_);
            docs_.push(lib);
            includes(*d, lib, libPrefix);
            collectGroups(*d, lib, libPrefix);
            docs_.pop();
        }
    }

    void collectGroups(const json& doc, const fs::path& file, const std::string& prefix) {
        if (!doc.contains("groups")) return;
        const json& groups = doc["groups"];
        if (!groups.is_object()) {
            diags_.push_back({prefix + "groups", "expected an object of group definitions"});
            return;
        }
        for (const auto& [name, def] : groups.items()) {
            const std::string p = prefix + "groups." + name;
            if (name.empty() || name.find('.') != std::string::npos) {
                diags_.push_back({p, "group name '" + name + "' must be non-empty without '.'"});
                continue;
            }
            if (!def.is_object()) {
                diags_.push_back({p, "expected a group definition (an object)"});
                continue;
            }
            checkKeys(def, {"comment", "inputs", "outputs", "params", "passes", "edges"}, p,
                      diags_);
            stringList(def, "inputs", p + ".inputs", diags_);
            stringList(def, "outputs", p + ".outputs", diags_);
            if (def.contains("params") && !def["params"].is_object())
                diags_.push_back({p + ".params", "expected an object of parameter defaults"});
            else if (def.contains("params"))  // checked here once, used per instance
                for (const auto& [k, decl] : def["params"].items()) {
                    json value;
                    GroupParamSpec spec;
                    parseGroupParam(decl, p + ".params." + k, value, spec, diags_);
                }
            if (!def.contains("passes") || !def["passes"].is_array())
                diags_.push_back({p + ".passes", "expected an array of passes"});
            if (def.contains("edges") && !def["edges"].is_array())
                diags_.push_back({p + ".edges", "expected an array of edges"});
            else if (def.contains("edges")) {  // checked here once, expanded per instance
                std::vector<EdgeItem> parsed;
                for (size_t i = 0; i < def["edges"].size(); ++i)
                    parseEdge(def["edges"][i], p + ".edges[" + std::to_string(i) + "]", parsed,
                              diags_);
            }
            auto [it, fresh] = docs_.groups.emplace(name, GroupDef{&def, p, file.string()});
            if (!fresh)
                diags_.push_back(
                    {p, "group '" + name + "' is already defined at " + it->second.origin});
        }
    }

private:
    Assembly extend(const json& doc, const fs::path& file, const std::string& prefix) {
        const std::string p = prefix + "extends";
        if (!doc["extends"].is_string()) {
            diags_.push_back({p, "expected the file name of the graph this one extends"});
            return {};
        }
        fs::path baseFile;
        const json* base = docs_.open(doc["extends"], file, p, "extends", baseFile);
        if (!base) return {};
        checkKeys(*base,
                  {"kestrel", "name", "comment", "passes", "edges", "outputs", "groups", "include",
                   "extends", "drop"},
                  baseFile.string() + ":", diags_);
        checkVersion(*base, baseFile.string() + ": ", diags_);
        docs_.push(baseFile);
        docs_.loaded(baseFile);
        Assembly a = assemble(*base, baseFile, baseFile.string() + ": ");
        docs_.pop();
        drop(doc, prefix, a);
        return a;
    }

    /// "drop": passes of the base graph left out, with every edge and output that touches them.
    void drop(const json& doc, const std::string& prefix, Assembly& a) {
        if (!doc.contains("drop")) return;
        std::set<std::string> names;
        for (const auto& n : stringList(doc, "drop", prefix + "drop", diags_)) {
            auto it = std::find_if(a.passes.begin(), a.passes.end(),
                                   [&](const PassItem& i) { return i.name == n; });
            if (it == a.passes.end()) {
                std::vector<std::string> known;
                for (const auto& i : a.passes) known.push_back(i.name);
                diags_.push_back({prefix + "drop", "the base graph has no pass '" + n +
                                                       "' (passes: " + join(known) + ")"});
                continue;
            }
            names.insert(n);
            a.passes.erase(it);
        }
        auto dropped = [&](const std::string& s) { return names.count(firstComponent(s)) > 0; };
        for (auto& e : a.edges) std::erase_if(e.to, dropped);
        std::erase_if(a.edges, [&](const EdgeItem& e) { return e.to.empty() || dropped(e.from); });
        std::erase_if(a.outputs, [&](const OutputItem& o) { return dropped(o.text); });
    }

    /// The document's passes; with "extends", one named as a base pass replaces it in place.
    void ownPasses(const json& doc, const std::string& prefix, Assembly& a, bool extending) {
        if (!doc.contains("passes")) {
            if (!extending) diags_.push_back({prefix + "passes", "expected an array of passes"});
            return;
        }
        const json& passes = doc["passes"];
        if (!passes.is_array()) {
            diags_.push_back({prefix + "passes", "expected an array of passes"});
            return;
        }
        for (size_t i = 0; i < passes.size(); ++i) {
            PassItem item{&passes[i], prefix + "passes[" + std::to_string(i) + "]", {}};
            if (passes[i].is_object() && passes[i].contains("name") &&
                passes[i]["name"].is_string())
                item.name = passes[i]["name"];
            auto it = std::find_if(a.passes.begin(), a.passes.end(), [&](const PassItem& b) {
                return extending && !item.name.empty() && b.name == item.name;
            });
            if (it != a.passes.end())
                *it = item;
            else
                a.passes.push_back(item);
        }
    }

    DocumentSet& docs_;
    std::vector<Diagnostic>& diags_;
};

}  // namespace

namespace {
std::string typeOfValue(const json& v) {
    if (v.is_boolean()) return "bool";
    if (v.is_number_integer()) return "int";
    if (v.is_number()) return "number";
    if (v.is_string()) return "string";
    return "";
}

std::string numberText(double d) {
    return d == double(int64_t(d)) ? std::to_string(int64_t(d)) : json(d).dump();
}
}  // namespace

void parseGroupParam(const json& decl, const std::string& path, json& value, GroupParamSpec& spec,
                     std::vector<Diagnostic>& diags) {
    if (!decl.is_object() || !decl.contains("default")) {  // a bare default: its type
        value = decl;
        spec.type = typeOfValue(decl);
        return;
    }
    checkKeys(decl, {"default", "type", "min", "max", "comment"}, path, diags);
    value = decl["default"];
    spec.type = typeOfValue(value);
    if (decl.contains("type")) {
        const json& t = decl["type"];
        if (!t.is_string() || (t != "int" && t != "number" && t != "bool" && t != "string"))
            diags.push_back({path + ".type",
                             "expected \"int\", \"number\", \"bool\" or "
                             "\"string\", got " +
                                 t.dump()});
        else
            spec.type = t;
    }
    if (decl.contains("min") || decl.contains("max")) {
        const bool numeric = spec.type == "int" || spec.type == "number";
        if (!numeric || !decl.value("min", json(0)).is_number() ||
            !decl.value("max", json(0)).is_number() || !decl.contains("min") ||
            !decl.contains("max")) {
            diags.push_back({path,
                             "\"min\" and \"max\" (both numbers) bound an int or number "
                             "parameter"});
        } else {
            spec.hasRange = true;
            spec.min = decl["min"];
            spec.max = decl["max"];
        }
    }
    if (auto bad = checkGroupValue(spec, value); !bad.empty())
        diags.push_back({path + ".default", bad});
}

std::string checkGroupValue(const GroupParamSpec& spec, const json& value) {
    const bool isInt =
        value.is_number_integer() ||
        (value.is_number_float() && value.get<double>() == std::floor(value.get<double>()) &&
         std::fabs(value.get<double>()) < 9e15);
    std::string expected;
    bool ok = true;
    if (spec.type == "int") {
        expected = "an integer";
        ok = isInt;
    } else if (spec.type == "number") {
        expected = "a number";
        ok = value.is_number();
    } else if (spec.type == "bool") {
        expected = "true or false";
        ok = value.is_boolean();
    } else if (spec.type == "string") {
        expected = "a string";
        ok = value.is_string();
    }
    if (ok && spec.hasRange) {
        const double v = value.get<double>();
        ok = v >= spec.min && v <= spec.max;
    }
    if (ok) return "";
    if (spec.hasRange)
        expected += " in [" + numberText(spec.min) + ", " + numberText(spec.max) + "]";
    return "expected " + expected + ", got " + value.dump();
}

void expandDocument(const json& doc, const fs::path& source, GraphDesc& g,
                    std::vector<Diagnostic>& diags) {
    DocumentSet docs(diags);
    if (!source.empty()) {
        docs.push(source);
        docs.loaded(source);
    }
    Assembler assembler(docs, diags);
    Assembly a = assembler.assemble(doc, source, "");
    expandAssembly(a, docs.groups, g, diags);
    if (!source.empty()) g.files.push_back(source);
    g.files.insert(g.files.end(), docs.files.begin(), docs.files.end());
}

std::vector<GroupInfo> groupsOfFile(const fs::path& file) {
    std::vector<Diagnostic> diags;
    const json doc = parseJsonText(readGraphText(file), file.string());
    if (!doc.is_object())
        throw GraphError({{file.string(), "expected a JSON object at the top level"}});
    DocumentSet docs(diags);
    docs.push(file);
    docs.loaded(file);
    Assembler assembler(docs, diags);
    assembler.includes(doc, file, file.string() + ": ");
    assembler.collectGroups(doc, file, file.string() + ": ");
    if (!diags.empty()) throw GraphError(std::move(diags));
    std::vector<GroupInfo> r;
    for (const auto& [name, def] : docs.groups) {
        if (def.file != file.lexically_normal().string() && def.file != file.string()) continue;
        const json& j = *def.j;
        GroupInfo info;
        info.name = name;
        info.file = def.file;
        if (j.contains("comment") && j["comment"].is_string()) info.comment = j["comment"];
        info.inputs = stringList(j, "inputs", "", diags);
        info.outputs = stringList(j, "outputs", "", diags);
        if (j.contains("params"))
            for (const auto& [k, decl] : j["params"].items()) {
                json value;
                GroupParamSpec spec;
                parseGroupParam(decl, "", value, spec, diags);
                info.params.emplace_back(k, value.dump());
            }
        info.passCount = j["passes"].size();
        r.push_back(std::move(info));
    }
    return r;
}

}  // namespace kestrel::detail
