// Group expansion (docs/graphs.md): instances of groups become flat passes named by their
// instance path ("diffuse.atrous0"), group parameters ("$name") are substituted, and edges to and
// from an instance's inputs and outputs are connected to the inner ports they stand for.
#include <algorithm>
#include <map>
#include <nlohmann/json.hpp>
#include <set>
#include <string>
#include <vector>

#include "GraphAssembly.h"
#include "GraphInternal.h"
#include "ParamCheck.h"

namespace kestrel::detail {

using nlohmann::json;

namespace {

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
    Expander(GraphDesc& g, const GroupTable& groups, std::vector<Diagnostic>& diags)
        : g_(g), groups_(groups), diags_(diags) {}

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
        auto def = groups_.find(gname);
        if (def == groups_.end()) {
            std::vector<std::string> known;
            for (const auto& [k, d] : groups_) known.push_back(k);
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
    const GroupTable& groups_;
    std::vector<Diagnostic>& diags_;
    std::set<std::string> outputsChecked_;  ///< groups whose unfed outputs were reported
};

}  // namespace

void expandAssembly(const Assembly& a, const GroupTable& groups, GraphDesc& g,
                    std::vector<Diagnostic>& diags) {
    Expander(g, groups, diags).expandTop(a);
}

}  // namespace kestrel::detail
