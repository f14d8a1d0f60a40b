// Groups, includes and extends (docs/graphs.md): turns a graph document into the flat GraphDesc.
// Every pass and edge keeps the JSON path it was written at (in its own file), so the compiler's
// messages point at the definition and name the instance path.
#include <algorithm>
#include <cmath>
#include <deque>
#include <filesystem>
#include <map>
#include <nlohmann/json.hpp>
#include <set>
#include <string>
#include <vector>

#include "GraphInternal.h"
#include "ParamCheck.h"

namespace kestrel::detail {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

// Instances of instances multiply: a few nested levels of a few instances each are already
// thousands of passes. A graph past this is a mistake (or a fuzzer), not a pipeline.
constexpr size_t kMaxExpandedPasses = 100000;
constexpr size_t kMaxNesting = 32;

struct PassItem {
    const json* j = nullptr;
    std::string origin;
    std::string name;
};
struct EdgeItem {
    std::string from;
    std::vector<std::string> to;
    bool toArray = false;
    bool history = false;
    std::string origin;
};
struct OutputItem {
    std::string text;
    std::string origin;
};
struct GroupDef {
    const json* j = nullptr;
    std::string origin;  ///< "graphs/lib/svgf-chain.json: groups.svgf-chain"
    std::string file;    ///< the file it is written in (display form)
};
/// A document's contents after include and extends: what the expansion works from.
struct Assembly {
    std::vector<PassItem> passes;
    std::vector<EdgeItem> edges;
    std::vector<OutputItem> outputs;
};

std::string join(const std::vector<std::string>& v, const char* sep = ", ") {
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

/// obj[key] as names (without '.'); problems are reported at `keyPath`.
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

/// One edge as written; "to" may be an array (one source feeding several inputs).
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

/// What an instance shows its surroundings: group inputs fan out to inner input ports, group
/// outputs come from one inner output port (all flat names).
struct Endpoint {
    std::string pass, port;
    bool history = false;
};
struct Interface {
    std::string group;
    std::vector<std::string> inputNames, outputNames;
    std::map<std::string, std::vector<Endpoint>> inputs;
    std::map<std::string, Endpoint> outputs;
};
/// Group parameter values inside one instance, and where a binding to each is recorded: the
/// instance itself and every enclosing instance whose parameter was passed down ("$x").
struct ParamEnv {
    std::string instance, group;
    std::map<std::string, json> values;
    std::map<std::string, std::vector<std::pair<size_t, std::string>>> targets;
};

class Expander {
public:
    Expander(GraphDesc& g, const DocumentSet& docs, std::vector<Diagnostic>& diags)
        : g_(g), docs_(docs), diags_(diags) {}

    void expandTop(const Assembly& a) {
        Scope top;
        expandScope(a.passes, a.edges, top);
        for (const auto& o : a.outputs) {
            auto inst = top.instances.find(firstComponent(o.text));
            const std::string rest =
                o.text.find('.') == std::string::npos ? "" : o.text.substr(o.text.find('.') + 1);
            if (inst != top.instances.end() && !rest.empty() &&
                rest.find('.') == std::string::npos) {
                auto out = inst->second.outputs.find(rest);
                if (out == inst->second.outputs.end()) {
                    diags_.push_back({o.origin, noPort(inst->first, inst->second, rest, false)});
                    continue;
                }
                g_.outputs.push_back(out->second.pass + "." + out->second.port);
            } else {
                g_.outputs.push_back(o.text);
            }
        }
    }

private:
    struct Scope {
        std::string prefix;              ///< "" or "diffuse." (flat names of this scope's passes)
        const ParamEnv* env = nullptr;   ///< group parameters (null at the top)
        Interface* iface = nullptr;      ///< the group's interface being built (null at the top)
        std::vector<std::string> stack;  ///< groups being expanded, outermost first
        std::map<std::string, Interface> instances;
    };
    struct Source {
        bool groupInput = false;
        std::string input;  ///< group input name when groupInput
        Endpoint at;
    };

    static std::string noPort(const std::string& inst, const Interface& i, const std::string& port,
                              bool input) {
        return "instance '" + inst + "' (group " + i.group + ") has no " +
               (input ? "input '" : "output '") + port + "' (" +
               (input ? "inputs: " : "outputs: ") +
               listOrNone(input ? i.inputNames : i.outputNames) + ")";
    }

    /// "$name" -> the group parameter's value; "$$x" -> the string "$x". Anything else as is.
    /// Returns false (after a diagnostic) for an unknown parameter.
    bool substitute(json& v, const Scope& s, const std::string& path, std::string* bound) {
        if (!v.is_string() || !s.env) return true;
        const std::string text = v;
        if (text.rfind("$$", 0) == 0) {
            v = text.substr(1);
            return true;
        }
        if (text.empty() || text[0] != '$') return true;
        const std::string name = text.substr(1);
        auto it = s.env->values.find(name);
        if (it == s.env->values.end()) {
            std::vector<std::string> known;
            for (const auto& [k, x] : s.env->values) known.push_back(k);
            diags_.push_back({path, "unknown group parameter '" + text +
                                        "' (parameters of group '" + s.env->group +
                                        "': " + (known.empty() ? "none" : join(known)) + ")"});
            return false;
        }
        v = it->second;
        if (bound) *bound = name;
        return true;
    }

    bool checkName(const json& jp, const std::string& p, const Scope& s,
                   std::set<std::string>& names, std::string& name) {
        if (!jp.contains("name") || !jp["name"].is_string() ||
            jp["name"].get<std::string>().empty()) {
            diags_.push_back({p + ".name", "expected a non-empty string"});
            return false;
        }
        name = jp["name"];
        if (name.find('.') != std::string::npos) {
            diags_.push_back({p + ".name", "pass name '" + name + "' must not contain '.'"});
            return false;
        }
        if (s.iface && (name == "in" || name == "out")) {
            diags_.push_back({p + ".name", "'" + name + "' names the group's own " +
                                               (name == "in" ? "inputs" : "outputs") +
                                               " inside a group; choose another pass name"});
            return false;
        }
        if (!names.insert(name).second) {
            diags_.push_back({p + ".name", "duplicate pass name '" + name + "'"});
            return false;
        }
        return true;
    }

    void expandScope(const std::vector<PassItem>& passes, const std::vector<EdgeItem>& edges,
                     Scope& s) {
        std::set<std::string> names;
        for (const auto& item : passes) {
            if (g_.passes.size() > kMaxExpandedPasses) return;
            const json& jp = *item.j;
            const std::string& p = item.origin;
            if (!jp.is_object()) {
                diags_.push_back({p, "expected an object with name and type (or group)"});
                continue;
            }
            const bool instance = jp.contains("group");
            checkKeys(jp,
                      instance ? std::set<std::string>{"name", "group", "params", "comment"}
                               : std::set<std::string>{"name", "type", "params", "comment"},
                      p, diags_);
            std::string name;
            const bool named = checkName(jp, p, s, names, name);
            if (jp.contains("params") && !jp["params"].is_object()) {
                diags_.push_back({p + ".params", "expected an object, got " + jp["params"].dump()});
                continue;
            }
            if (instance) {
                if (named) instantiate(jp, p, s, name);
                continue;
            }
            plainPass(jp, p, s, name);
        }
        for (const auto& e : edges) expandEdge(e, s);
    }

    void plainPass(const json& jp, const std::string& p, const Scope& s, const std::string& name) {
        PassNode n;
        n.name = s.prefix + name;
        n.origin = p;
        if (!s.prefix.empty()) n.instance = s.prefix.substr(0, s.prefix.size() - 1);
        if (!jp.contains("type") || !jp["type"].is_string())
            diags_.push_back({p + ".type", "expected a pass type name (string)"});
        else
            n.type = jp["type"];
        if (jp.contains("params")) {
            json params = jp["params"];
            for (auto& [k, v] : params.items()) {
                std::string bound;
                substitute(v, s, p + ".params." + k, &bound);
                if (bound.empty()) continue;
                n.boundParams[k] = s.env->instance + "." + bound;
                for (const auto& [idx, gp] : s.env->targets.at(bound))
                    g_.instances[idx].bindings[gp].emplace_back(n.name, k);
            }
            n.paramsJson = params.dump();
        }
        if (jp.contains("comment") && jp["comment"].is_string()) n.comment = jp["comment"];
        g_.passes.push_back(std::move(n));
        if (g_.passes.size() > kMaxExpandedPasses)
            diags_.push_back({p, "the graph expands to more than " +
                                     std::to_string(kMaxExpandedPasses) +
                                     " passes (groups instantiated inside groups too often?)"});
    }

    void instantiate(const json& jp, const std::string& p, Scope& s, const std::string& name) {
        if (!jp["group"].is_string()) {
            diags_.push_back({p + ".group", "expected a group name (string)"});
            return;
        }
        const std::string gname = jp["group"];
        auto def = docs_.groups.find(gname);
        if (def == docs_.groups.end()) {
            std::vector<std::string> known;
            for (const auto& [k, d] : docs_.groups) known.push_back(k);
            std::string near = nearestName(gname, known);
            diags_.push_back(
                {p + ".group",
                 "unknown group '" + gname + "'" +
                     (!near.empty()   ? " (did you mean '" + near + "'?)"
                      : known.empty() ? " (no groups defined: see \"groups\" and \"include\")"
                                      : " (groups: " + join(known) + ")")});
            return;
        }
        if (std::find(s.stack.begin(), s.stack.end(), gname) != s.stack.end()) {
            std::vector<std::string> cycle(std::find(s.stack.begin(), s.stack.end(), gname),
                                           s.stack.end());
            cycle.push_back(gname);
            diags_.push_back({p + ".group", "group cycle: " + join(cycle, " -> ")});
            return;
        }
        if (s.stack.size() >= kMaxNesting) {
            diags_.push_back(
                {p + ".group", "groups nested more than " + std::to_string(kMaxNesting) + " deep"});
            return;
        }
        const json& dj = *def->second.j;
        if (!dj.contains("passes") || !dj["passes"].is_array())
            return;  // reported at the definition

        ParamEnv env;
        env.instance = s.prefix + name;
        env.group = gname;
        const size_t idx = g_.instances.size();
        g_.instances.push_back({env.instance, gname, p, {}});
        const json defaults =
            dj.contains("params") && dj["params"].is_object() ? dj["params"] : json::object();
        std::vector<Diagnostic> reported;  // at the definition, when it was read
        for (const auto& [k, decl] : defaults.items()) {
            parseGroupParam(decl, "", env.values[k], g_.instances[idx].specs[k], reported);
            env.targets[k] = {{idx, k}};
        }
        if (jp.contains("params"))
            for (const auto& [k, v] : jp["params"].items()) {
                const std::string pp = p + ".params." + k;
                if (!defaults.contains(k)) {
                    std::vector<std::string> known;
                    for (const auto& [d, x] : defaults.items()) known.push_back(d);
                    std::string near = nearestName(k, known);
                    diags_.push_back(
                        {pp, "group '" + gname + "' has no parameter '" + k + "'" +
                                 (!near.empty()
                                      ? " (did you mean '" + near + "'?)"
                                      : " (parameters: " + (known.empty() ? "none" : join(known)) +
                                            ")")});
                    continue;
                }
                json value = v;
                std::string bound;
                if (!substitute(value, s, pp, &bound)) continue;
                if (auto bad = checkGroupValue(g_.instances[idx].specs[k], value); !bad.empty()) {
                    diags_.push_back(
                        {pp, "group parameter '" + k + "' of group '" + gname + "': " + bad});
                    continue;
                }
                env.values[k] = value;
                if (!bound.empty()) {  // passed down: the outer parameter drives it too
                    auto& t = env.targets[k];
                    const auto& outer = s.env->targets.at(bound);
                    t.insert(t.begin(), outer.begin(), outer.end());
                }
            }

        Interface iface;
        iface.group = gname;
        std::vector<Diagnostic> ignored;  // reported once, when the definition was read
        iface.inputNames = stringList(dj, "inputs", "", ignored);
        iface.outputNames = stringList(dj, "outputs", "", ignored);
        Scope inner;
        inner.prefix = env.instance + ".";
        inner.env = &env;
        inner.iface = &iface;
        inner.stack = s.stack;
        inner.stack.push_back(gname);
        std::vector<PassItem> passes;
        const json& dp = dj["passes"];
        for (size_t i = 0; i < dp.size(); ++i)
            passes.push_back(
                {&dp[i], def->second.origin + ".passes[" + std::to_string(i) + "]", {}});
        std::vector<EdgeItem> edges;
        if (dj.contains("edges") && dj["edges"].is_array())
            for (size_t i = 0; i < dj["edges"].size(); ++i)
                parseEdge(dj["edges"][i], def->second.origin + ".edges[" + std::to_string(i) + "]",
                          edges, ignored);
        expandScope(passes, edges, inner);
        if (outputsChecked_.insert(gname).second)
            for (const auto& o : iface.outputNames)
                if (!iface.outputs.count(o))
                    diags_.push_back(
                        {def->second.origin + ".outputs",
                         "group output '" + o + "' is not fed: add an edge to \"out." + o + "\""});
        s.instances[name] = std::move(iface);
    }

    /// Where an edge's "from" reads: a pass of this scope, an instance's output, or (inside a
    /// group) one of the group's inputs.
    bool resolveSource(const EdgeItem& e, const Scope& s, Source& src) {
        const std::string local = firstComponent(e.from);
        const std::string rest = e.from.substr(local.size() + 1);
        const std::string path = e.origin + ".from";
        if (s.iface && local == "in") {
            if (std::find(s.iface->inputNames.begin(), s.iface->inputNames.end(), rest) ==
                s.iface->inputNames.end()) {
                diags_.push_back({path, "group '" + s.iface->group + "' declares no input '" +
                                            rest + "' (inputs: " + listOrNone(s.iface->inputNames) +
                                            ")"});
                return false;
            }
            src.groupInput = true;
            src.input = rest;
            return true;
        }
        auto inst = s.instances.find(local);
        if (inst != s.instances.end() && rest.find('.') == std::string::npos) {
            auto out = inst->second.outputs.find(rest);
            if (out == inst->second.outputs.end()) {
                diags_.push_back({path, noPort(local, inst->second, rest, false)});
                return false;
            }
            src.at = out->second;
            return true;
        }
        splitPassPort(s.prefix + e.from, src.at.pass, src.at.port);
        return true;
    }

    void expandEdge(const EdgeItem& e, Scope& s) {
        Source src;
        if (!resolveSource(e, s, src)) return;
        for (size_t k = 0; k < e.to.size(); ++k) {
            const std::string& to = e.to[k];
            const std::string path =
                e.origin + ".to" + (e.toArray ? "[" + std::to_string(k) + "]" : "");
            const std::string local = firstComponent(to);
            const std::string rest = to.substr(local.size() + 1);
            if (s.iface && local == "out") {
                groupOutput(e, s, src, rest, path);
                continue;
            }
            auto inst = s.instances.find(local);
            if (inst != s.instances.end() && rest.find('.') == std::string::npos) {
                const auto& names = inst->second.inputNames;
                if (std::find(names.begin(), names.end(), rest) == names.end()) {
                    diags_.push_back({path, noPort(local, inst->second, rest, true)});
                    continue;
                }
                for (const auto& d : inst->second.inputs[rest]) connect(e, s, src, d);
                continue;
            }
            Endpoint d;
            splitPassPort(s.prefix + to, d.pass, d.port);
            connect(e, s, src, d);
        }
    }

    void groupOutput(const EdgeItem& e, Scope& s, const Source& src, const std::string& name,
                     const std::string& path) {
        const auto& names = s.iface->outputNames;
        if (std::find(names.begin(), names.end(), name) == names.end())
            diags_.push_back({path, "group '" + s.iface->group + "' declares no output '" + name +
                                        "' (outputs: " + listOrNone(names) + ")"});
        else if (src.groupInput)
            diags_.push_back({path,
                              "a group output must come from a pass inside the group, not "
                              "straight from in." +
                                  src.input});
        else if (e.history)
            diags_.push_back({path, "an edge to a group output cannot be a history edge"});
        else if (!s.iface->outputs.emplace(name, src.at).second)
            diags_.push_back({path, "group output '" + name + "' is already fed"});
    }

    void connect(const EdgeItem& e, Scope& s, const Source& src, const Endpoint& d) {
        if (e.history && d.history) {
            diags_.push_back({e.origin + ".history",
                              "history edge into a group input that the group already reads as "
                              "history (" +
                                  d.pass + "." + d.port + ")"});
            return;
        }
        const bool history = e.history || d.history;
        if (src.groupInput) {
            s.iface->inputs[src.input].push_back({d.pass, d.port, history});
            return;
        }
        g_.edges.push_back({src.at.pass, src.at.port, d.pass, d.port, history, e.origin});
    }

    GraphDesc& g_;
    const DocumentSet& docs_;
    std::vector<Diagnostic>& diags_;
    std::set<std::string> outputsChecked_;  ///< groups whose unfed outputs were reported
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
    Expander(g, docs, diags).expandTop(a);
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
