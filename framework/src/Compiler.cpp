// The graph compiler: validate -> instantiate -> resolve -> prune -> order -> plan memory.
#include "kestrel/Compiler.h"

#include <algorithm>
#include <cstdio>
#include <functional>
#include <map>
#include <nlohmann/json.hpp>
#include <numeric>
#include <optional>
#include <set>
#include <sstream>

#include "CompilerImpl.h"
#include "ParamCheck.h"

namespace kestrel {

using nlohmann::json;

namespace {

struct PortRef {
    int node = -1, port = -1;
    bool operator==(const PortRef&) const = default;
};

std::string portList(const PassDesc& d, PortKind kind) {
    std::string s;
    for (const auto& p : d.ports)
        if (p.kind == kind) s += (s.empty() ? "" : ", ") + p.name;
    return s.empty() ? "none" : s;
}

int portIndex(const PassDesc& d, std::string_view name, PortKind kind) {
    for (size_t i = 0; i < d.ports.size(); ++i)
        if (d.ports[i].name == name && d.ports[i].kind == kind) return int(i);
    return -1;
}

/// History memory lent to transient resources while it is idle (CompileOptions::historyIdle):
/// last frame's value is dead once its last reader has run, until this frame's is written over
/// it (one buffer) or to the end of the frame (two buffers: this frame's is in the other).
class IdleHistory {
public:
    IdleHistory(const std::vector<ResourceInfo>& resources, int end) {
        for (size_t h = 0; h < resources.size(); ++h) {
            const ResourceInfo& r = resources[h];
            if (!r.history) continue;
            const int until = r.doubleBuffered ? end : r.firstUse;
            for (int c = 0; c < channelCount(r.format); ++c)
                planes_.push_back({{int(h), c}, r.lastHistoryRead + 1, until});
        }
    }

    /// `count` planes idle through steps [first, last], now taken; none if there are fewer.
    std::vector<HistoryPlane> take(int count, int first, int last) {
        std::vector<Slot*> found;
        for (Slot& s : planes_)
            if (int(found.size()) < count && s.from <= first && last < s.until &&
                s.busyUntil < first)
                found.push_back(&s);
        return claim(found, count, last);
    }

    /// Every plane of the one-buffer history resource `h`, idle from step `first` until its
    /// producer writes it, now taken: that pass writes it in place of the resource taking them.
    std::vector<HistoryPlane> takeWhole(int h, int first) {
        std::vector<Slot*> found;
        int count = 0;
        for (Slot& s : planes_)
            if (s.plane.resource == h) {
                ++count;
                if (s.from <= first && s.busyUntil < first) found.push_back(&s);
            }
        return claim(found, count, found.empty() ? 0 : found.front()->until);
    }

private:
    struct Slot {
        HistoryPlane plane;
        int from, until;     // idle in steps [from, until)
        int busyUntil = -1;  // last step of the resource holding it
    };
    static std::vector<HistoryPlane> claim(const std::vector<Slot*>& found, int count, int last) {
        if (count == 0 || int(found.size()) < count) return {};
        std::vector<HistoryPlane> out;
        for (Slot* s : found) {
            s->busyUntil = last;
            out.push_back(s->plane);
        }
        return out;
    }
    std::vector<Slot> planes_;
};

class Compiler {
public:
    Compiler(const GraphDesc& desc, const Registry& registry, const CompileOptions& options)
        : registry_(registry), options_(options), g_(std::make_unique<CompiledGraph::Impl>()) {
        g_->desc = desc;
    }

    std::unique_ptr<CompiledGraph::Impl> run() {
        instantiate();
        bindEdges();
        checkOutputs();
        if (diags_.empty()) order();
        if (diags_.empty()) construct();
        if (!diags_.empty()) throw GraphError(relocate(std::move(diags_)));
        if (options_.validateOnly) return std::move(g_);
        resolve();
        markLive();
        if (options_.fuse) fuse();
        g_->stepOf.resize(g_->order.size());
        if (g_->steps == 0)  // not fused: one pass per step
            for (size_t k = 0; k < g_->order.size(); ++k) g_->stepOf[k] = int(k);
        g_->steps = g_->order.empty() ? 0 : g_->stepOf.back() + 1;
        planResources();
        return std::move(g_);
    }

private:
    NodeState& node(int i) { return g_->nodes[size_t(i)]; }
    const PassDesc& descOf(int i) { return node(i).type->desc; }
    const EdgeDesc& edge(int e) { return g_->desc.edges[size_t(e)]; }
    std::string portName(PortRef r) {
        return node(r.node).name + "." + descOf(r.node).ports[size_t(r.port)].name;
    }

    /// Diagnostics name passes and edges by their index in the flat graph; the user wrote them
    /// elsewhere (an instance expands to many passes, a group may live in another file). Each
    /// gets the JSON path where it is written, and the pass (parameter) it concerns by name.
    std::vector<Diagnostic> relocate(std::vector<Diagnostic> diags) const {
        const GraphDesc& d = g_->desc;
        for (auto& diag : diags) {
            size_t index = 0;
            int consumed = 0;
            if (std::sscanf(diag.path.c_str(), "passes[%zu]%n", &index, &consumed) == 1 &&
                consumed > 0 && index < d.passes.size()) {
                const PassNode& n = d.passes[index];
                const std::string rest = diag.path.substr(size_t(consumed));
                diag.label = n.name;
                const std::string params = ".params.";
                const std::string key =
                    rest.rfind(params, 0) == 0 ? rest.substr(params.size()) : std::string();
                const std::string param = key.substr(0, key.find('.'));
                if (!key.empty()) diag.label += "." + key;
                if (auto b = n.boundParams.find(param); !key.empty() && b != n.boundParams.end())
                    diag.message += " (set by group parameter " + b->second + ")";
                if (auto by = n.setBy.find(param); !key.empty() && by != n.setBy.end())
                    diag.path = by->second;  // from the command line: the option is to fix
                else if (!n.origin.empty())
                    diag.path = n.origin + rest;
            } else if (std::sscanf(diag.path.c_str(), "edges[%zu]%n", &index, &consumed) == 1 &&
                       consumed > 0 && index < d.edges.size() && !d.edges[index].origin.empty()) {
                diag.path = d.edges[index].origin + diag.path.substr(size_t(consumed));
            }
        }
        return mergeOptionDiagnostics(std::move(diags));
    }

    /// One line per command-line mistake: a group parameter set out of range drives several
    /// inner parameters, each refusing the same value ("--set single.sigmaLWide=-1
    /// (single.atrous2.sigmaL, single.atrous3.sigmaL, ...)").
    static std::vector<Diagnostic> mergeOptionDiagnostics(std::vector<Diagnostic> diags) {
        std::vector<Diagnostic> merged;
        for (auto& d : diags) {
            auto same = std::find_if(merged.begin(), merged.end(), [&](const Diagnostic& m) {
                return d.path.rfind("--", 0) == 0 && m.path == d.path && m.message == d.message;
            });
            if (same == merged.end())
                merged.push_back(std::move(d));
            else
                same->label += ", " + d.label;
        }
        return merged;
    }

    void instantiate() {
        const auto& passes = g_->desc.passes;
        for (size_t i = 0; i < passes.size(); ++i) {
            NodeState n;
            n.name = passes[i].name;
            n.jsonIndex = int(i);
            std::string path = "passes[" + std::to_string(i) + "]";
            n.type = registry_.find(passes[i].type);
            if (!n.type) {
                std::string msg = "unknown pass type '" + passes[i].type + "'";
                std::string near = registry_.nearest(passes[i].type);
                if (!near.empty())
                    msg += " (did you mean '" + near + "'?)";
                else
                    msg += " (see `kestrel passes` for the registered types)";
                diags_.push_back({path + ".type", msg});
            } else {
                n.params = detail::checkParams(n.type->desc, json::parse(passes[i].paramsJson),
                                               path, diags_);
                size_t ports = n.type->desc.ports.size();
                n.inEdge.assign(ports, -1);
                n.outAbsent.assign(ports, false);
                n.absentReason.assign(ports, {});
                n.rootCause.assign(ports, {});
                n.forward.assign(ports, -1);
                n.portResource.assign(ports, -1);
                n.portHistory.assign(ports, false);
            }
            byName_[n.name] = int(i);
            g_->nodes.push_back(std::move(n));
        }
    }

    /// The node named `name`; else a diagnostic at `path` (the full JSON path) and -1.
    int findNode(const std::string& name, const std::string& path) {
        auto it = byName_.find(name);
        if (it != byName_.end()) return it->second;
        std::vector<std::string> names;
        for (const auto& n : g_->nodes) names.push_back(n.name);
        std::string msg = "unknown pass '" + name + "'";
        std::string near = detail::nearestName(name, names);
        if (!near.empty()) msg += " (did you mean '" + near + "'?)";
        diags_.push_back({path, msg});
        return -1;
    }

    void bindEdges() {
        const auto& edges = g_->desc.edges;
        for (size_t ei = 0; ei < edges.size(); ++ei) {
            const auto& e = edges[ei];
            std::string path = "edges[" + std::to_string(ei) + "]";
            int s = findNode(e.fromPass, path + ".from");
            int d = findNode(e.toPass, path + ".to");
            int sp = -1, dp = -1;
            if (s >= 0 && node(s).type) {
                sp = portIndex(descOf(s), e.fromPort, PortKind::Output);
                if (sp < 0)
                    diags_.push_back(
                        {path + ".from", "pass '" + e.fromPass + "' (" + descOf(s).type +
                                             ") has no output '" + e.fromPort + "' (outputs: " +
                                             portList(descOf(s), PortKind::Output) + ")"});
            }
            if (d >= 0 && node(d).type) {
                dp = portIndex(descOf(d), e.toPort, PortKind::Input);
                if (dp < 0)
                    diags_.push_back(
                        {path + ".to", "pass '" + e.toPass + "' (" + descOf(d).type +
                                           ") has no input '" + e.toPort + "' (inputs: " +
                                           portList(descOf(d), PortKind::Input) + ")"});
            }
            if (sp < 0 || dp < 0) continue;
            const PortDesc& out = descOf(s).ports[size_t(sp)];
            const PortDesc& in = descOf(d).ports[size_t(dp)];
            if (out.format != Format::Any && !formatAccepts(in.format, out.format))
                diags_.push_back({path, "format mismatch: " + e.fromPass + "." + e.fromPort +
                                            " is " + std::string(formatName(out.format)) + " but " +
                                            e.toPass + "." + e.toPort + " expects " +
                                            std::string(formatName(in.format))});
            if (e.history && !in.history)
                diags_.push_back({path + ".history", e.toPass + "." + e.toPort +
                                                         " is not a history input; remove "
                                                         "\"history\": true"});
            if (!e.history && in.history)
                diags_.push_back({path, e.toPass + "." + e.toPort +
                                            " is a history input (previous frame): mark the edge "
                                            "\"history\": true"});
            int& slot = node(d).inEdge[size_t(dp)];
            if (slot >= 0) {
                diags_.push_back({path + ".to", "input " + e.toPass + "." + e.toPort +
                                                    " is already fed by edges[" +
                                                    std::to_string(slot) + "]"});
                continue;
            }
            slot = int(ei);
        }
        for (size_t i = 0; i < g_->nodes.size(); ++i) {
            auto& n = g_->nodes[i];
            if (!n.type) continue;
            const auto& ports = n.type->desc.ports;
            for (size_t p = 0; p < ports.size(); ++p)
                if (ports[p].kind == PortKind::Input && !ports[p].optional && n.inEdge[p] < 0)
                    diags_.push_back({"passes[" + std::to_string(i) + "]",
                                      "required input '" + ports[p].name + "' of pass '" + n.name +
                                          "' (" + n.type->desc.type + ") is not connected"});
        }
    }

    void checkOutputs() {
        for (size_t i = 0; i < g_->desc.outputs.size(); ++i) {
            const std::string& o = g_->desc.outputs[i];
            std::string path = "outputs[" + std::to_string(i) + "]";
            // "pass" or "pass.port"; pass names of group instances contain dots themselves.
            auto dot = byName_.count(o) ? std::string::npos : o.rfind('.');
            std::string pass = o.substr(0, dot);
            int n = findNode(pass, path);
            if (n < 0 || !node(n).type) continue;
            if (dot == std::string::npos) {
                rootNodes_.push_back(n);
                continue;
            }
            std::string port = o.substr(dot + 1);
            int p = portIndex(descOf(n), port, PortKind::Output);
            if (p < 0) {
                diags_.push_back({path, "pass '" + pass + "' has no output '" + port +
                                            "' (outputs: " + portList(descOf(n), PortKind::Output) +
                                            ")"});
                continue;
            }
            g_->marked.push_back({n, p});
            g_->markedNames.push_back(o);
        }
    }

    /// Topological order over same-frame edges; smallest JSON index first among ready passes,
    /// so the order is deterministic and follows the file where the graph allows.
    void order() {
        size_t n = g_->nodes.size();
        std::vector<std::vector<int>> succ(n), pred(n);
        std::vector<int> indeg(n, 0);
        for (size_t i = 0; i < n; ++i)
            for (int e : g_->nodes[i].inEdge) {
                if (e < 0 || edge(e).history) continue;
                int s = byName_[edge(e).fromPass];
                succ[size_t(s)].push_back(int(i));
                pred[i].push_back(s);
                ++indeg[i];
            }
        std::set<int> ready;
        for (size_t i = 0; i < n; ++i)
            if (indeg[i] == 0) ready.insert(int(i));
        while (!ready.empty()) {
            int v = *ready.begin();
            ready.erase(ready.begin());
            g_->topo.push_back(v);
            for (int w : succ[size_t(v)])
                if (--indeg[size_t(w)] == 0) ready.insert(w);
        }
        if (g_->topo.size() == n) return;
        // Name one cycle: walk predecessors among the unsorted passes until one repeats.
        std::vector<bool> sorted(n, false);
        for (int v : g_->topo) sorted[size_t(v)] = true;
        int start = 0;
        while (sorted[size_t(start)]) ++start;
        std::vector<int> path;
        std::map<int, size_t> seen;
        int v = start;
        while (!seen.count(v)) {
            seen[v] = path.size();
            path.push_back(v);
            for (int p : pred[size_t(v)])
                if (!sorted[size_t(p)]) {
                    v = p;
                    break;
                }
        }
        std::vector<int> cycle(path.begin() + long(seen[v]), path.end());
        std::reverse(cycle.begin(), cycle.end());
        std::string s;
        for (int c : cycle) s += node(c).name + " -> ";
        s += node(cycle.front()).name;
        diags_.push_back({"edges", "cycle without a history edge: " + s +
                                       " (mark the edge that carries last frame's value "
                                       "\"history\": true)"});
    }

    void construct() {
        for (auto& n : g_->nodes) {
            try {
                n.pass = n.type->create(n.params);
            } catch (const std::exception& e) {
                diags_.push_back(
                    {"passes[" + std::to_string(n.jsonIndex) + "]",
                     "pass '" + n.name + "' (" + n.type->desc.type + "): " + e.what()});
            }
        }
    }

    /// The output that really produces what `input` of node `n` reads: follows forwards.
    /// nullopt when unconnected or absent (reason in `why`).
    std::optional<PortRef> sourceOf(int n, int input, std::string* why = nullptr,
                                    std::vector<int>* via = nullptr, std::string* root = nullptr) {
        int e = node(n).inEdge[size_t(input)];
        for (int hops = 0; hops < 1000; ++hops) {
            if (e < 0) return std::nullopt;
            PortRef r{byName_[edge(e).fromPass], -1};
            r.port = portIndex(descOf(r.node), edge(e).fromPort, PortKind::Output);
            NodeState& s = node(r.node);
            if (s.outAbsent[size_t(r.port)]) {
                // Name the producer and the origin of the absence, not the whole chain between.
                const std::string& origin =
                    s.rootCause[size_t(r.port)].empty()
                        ? portName(r) + " is absent (" + s.absentReason[size_t(r.port)] + ")"
                        : s.rootCause[size_t(r.port)];
                if (why)
                    *why =
                        s.absent ? "pass '" + s.name + "' is left out because " + origin : origin;
                if (root) *root = origin;
                return std::nullopt;
            }
            int f = s.forward[size_t(r.port)];
            if (f < 0) return r;
            if (via) via->push_back(r.node);
            e = s.inEdge[size_t(f)];
        }
        throw Error("forwarding loop at pass '" + node(n).name + "'");
    }

    class Resolver final : public ResolveContext {
    public:
        Resolver(Compiler& c, int n) : c_(c), n_(n) {}
        bool isBound(std::string_view input) const override {
            int p = port(input, PortKind::Input);
            auto& nd = c_.node(n_);
            if (nd.inEdge[size_t(p)] < 0) return false;
            if (c_.edge(nd.inEdge[size_t(p)]).history) return true;  // settled after resolve
            return c_.sourceOf(n_, p).has_value();
        }
        std::string unboundReason(std::string_view input) const override {
            const int p = port(input, PortKind::Input);
            if (c_.node(n_).inEdge[size_t(p)] < 0) return "not connected";
            std::string root;
            if (c_.sourceOf(n_, p, nullptr, nullptr, &root)) return {};
            return root;
        }
        void forward(std::string_view output, std::string_view input) override {
            int o = port(output, PortKind::Output), i = port(input, PortKind::Input);
            if (!isBound(input))
                throw Error("pass '" + c_.node(n_).name + "' forwards '" + std::string(output) +
                            "' to unbound input '" + std::string(input) + "'");
            c_.node(n_).forward[size_t(o)] = i;
        }
        void setAbsent(std::string_view output, std::string reason) override {
            int o = port(output, PortKind::Output);
            c_.node(n_).outAbsent[size_t(o)] = true;
            c_.node(n_).absentReason[size_t(o)] = std::move(reason);
        }
        void ignoreInput(std::string_view input, std::string reason) override {
            const int p = port(input, PortKind::Input);
            auto& nd = c_.node(n_);
            if (nd.inEdge[size_t(p)] < 0) return;
            nd.inEdge[size_t(p)] = -1;
            note("input '" + std::string(input) + "' not read: " + reason);
        }
        void note(std::string message) override {
            c_.node(n_).notes.push_back(message);
            c_.g_->report.notes.push_back(c_.node(n_).name + ": " + message);
        }
        void setFact(std::string key, std::string value) override {
            c_.g_->report.facts[std::move(key)] = std::move(value);
        }
        std::optional<std::string> fact(std::string_view key) const override {
            const auto& facts = c_.g_->report.facts;
            const auto it = facts.find(std::string(key));
            if (it == facts.end()) return std::nullopt;
            return it->second;
        }
        int64_t firstFrame() const override { return c_.options_.firstFrame; }
        std::string_view passName() const override { return c_.node(n_).name; }

    private:
        int port(std::string_view name, PortKind kind) const {
            int p = portIndex(c_.descOf(n_), name, kind);
            if (p < 0)
                throw Error("pass '" + c_.node(n_).name + "' (" + c_.descOf(n_).type + ") has no " +
                            (kind == PortKind::Input ? "input" : "output") + " '" +
                            std::string(name) + "'");
            return p;
        }
        Compiler& c_;
        int n_;
    };

    void resolve() {
        for (int v : g_->topo) {
            NodeState& n = node(v);
            const auto& ports = descOf(v).ports;
            for (size_t p = 0; p < ports.size(); ++p) {
                if (ports[p].kind != PortKind::Input || ports[p].optional || n.inEdge[p] < 0)
                    continue;
                std::string why, root;
                if (!sourceOf(v, int(p), &why, nullptr, &root)) {
                    n.absent = true;
                    n.absentWhy = "input '" + ports[p].name + "' has no data: " + why;
                    for (size_t q = 0; q < ports.size(); ++q)
                        if (ports[q].kind == PortKind::Output) {
                            n.outAbsent[q] = true;
                            n.absentReason[q] = "pass '" + n.name + "' is left out";
                            n.rootCause[q] = root;
                        }
                    break;
                }
            }
            if (n.absent) continue;
            Resolver rc(*this, v);
            try {
                n.pass->resolve(rc);
            } catch (const GraphError&) {
                throw;
            } catch (const std::exception& e) {
                throw Error("pass '" + n.name + "' (" + descOf(v).type + "): " + e.what());
            }
            for (size_t p = 0; p < ports.size(); ++p)
                if (n.outAbsent[p])
                    g_->report.absent.push_back(n.name + "." + ports[p].name + ": " +
                                                n.absentReason[p]);
        }
    }

    void markLive() {
        std::function<void(int)> live = [&](int v) {
            NodeState& n = node(v);
            if (n.executed) return;
            n.executed = n.live = true;
            const auto& ports = descOf(v).ports;
            for (size_t p = 0; p < ports.size(); ++p) {
                if (ports[p].kind != PortKind::Input) continue;
                std::vector<int> via;
                if (auto src = sourceOf(v, int(p), nullptr, &via)) {
                    for (int f : via) node(f).live = true;
                    live(src->node);
                }
            }
        };
        auto rootFail = [&](const std::string& what, const std::string& why) {
            throw Error(what + " cannot be produced for this scene: " + why);
        };
        for (size_t v = 0; v < g_->nodes.size(); ++v)
            if (descOf(int(v)).sink) {
                if (node(int(v)).absent)
                    rootFail("output pass '" + node(int(v)).name + "'", node(int(v)).absentWhy);
                live(int(v));
            }
        for (int v : rootNodes_) {
            if (node(v).absent) rootFail("output pass '" + node(v).name + "'", node(v).absentWhy);
            live(v);
        }
        for (size_t m = 0; m < g_->marked.size(); ++m) {
            auto [v, p] = g_->marked[m];
            NodeState& n = node(v);
            if (n.outAbsent[size_t(p)])
                rootFail("output " + g_->markedNames[m],
                         n.absentReason[size_t(p)] + (n.rootCause[size_t(p)].empty()
                                                          ? std::string()
                                                          : " because " + n.rootCause[size_t(p)]));
            int f = n.forward[size_t(p)];
            if (f < 0) {
                live(v);
                continue;
            }
            n.live = true;
            std::vector<int> via;
            if (auto src = sourceOf(v, f, nullptr, &via)) {
                for (int x : via) node(x).live = true;
                g_->marked[m] = {src->node, src->port};
                live(src->node);
            }
        }
        for (int v : g_->topo) {
            NodeState& n = node(v);
            if (n.executed) {
                g_->order.push_back(v);
                continue;
            }
            if (n.absent) {
                g_->report.pruned.push_back({n.name, n.absentWhy});
            } else if (n.live) {
                // Without a note of its own the pass is the identity for its parameters.
                if (n.notes.empty())
                    g_->report.elided.push_back(
                        {n.name, "identity for this scene (outputs forwarded)", true});
                else
                    g_->report.elided.push_back({n.name, n.notes.back(), false});
            } else {
                g_->report.pruned.push_back({n.name, "contributes to no output"});
            }
        }
    }

    /// The fusion key of executed node v: its type, fusionKey() and where its fuseOn inputs
    /// come from; empty where it cannot fuse.
    /// ... and which of its outputs are consumed (`consumed`: node, output port), so that the
    /// members of a step produce the same outputs, unless the type fuses members whose outputs
    /// differ (FusedOutputs::MayDiffer).
    std::string fusionKeyOf(int v, const std::set<std::pair<int, int>>& consumed) {
        const PassDesc& d = descOf(v);
        if (d.fusedInputs.empty()) return {};
        std::string key = node(v).pass->fusionKey();
        if (key.empty()) return {};
        key = d.type + "|" + key;
        for (const auto& name : d.fusedInputs) {
            const int p = portIndex(d, name, PortKind::Input);
            const int e = node(v).inEdge[size_t(p)];
            const auto src = sourceOf(v, p);
            key += src ? "|" + portName(*src) + (edge(e).history ? "@prev" : "") : "|-";
        }
        if (d.fusedOutputsMayDiffer) return key;
        key += "|out:";
        for (size_t p = 0; p < d.ports.size(); ++p)
            if (d.ports[p].kind == PortKind::Output) key += consumed.count({v, int(p)}) ? '1' : '0';
        return key;
    }

    /// The outputs of executed passes that something reads (this frame or the next) or marks.
    std::set<std::pair<int, int>> consumedOutputs() {
        std::set<std::pair<int, int>> consumed(g_->marked.begin(), g_->marked.end());
        for (int v : g_->order) {
            const auto& ports = descOf(v).ports;
            for (size_t p = 0; p < ports.size(); ++p)
                if (ports[p].kind == PortKind::Input)
                    if (const auto src = sourceOf(v, int(p)))
                        consumed.insert({src->node, src->port});
        }
        return consumed;
    }

    /// The execution order with each group of `groups` (execution indices) contracted into one
    /// step: a topological sort of the contracted dependencies (`preds`), smallest original index
    /// first among ready steps. False if the contraction has a cycle.
    bool contract(const std::vector<std::vector<int>>& groups,
                  const std::vector<std::vector<int>>& preds, std::vector<int>& order,
                  std::vector<int>& stepOf, int& steps) {
        const size_t n = g_->order.size();
        std::vector<int> unit(n);  // execution index -> unit (its group's first member)
        std::vector<std::vector<int>> members(n);
        std::iota(unit.begin(), unit.end(), 0);
        for (size_t k = 0; k < n; ++k) members[k] = {int(k)};
        for (const auto& group : groups)
            for (size_t i = 1; i < group.size(); ++i) {
                unit[size_t(group[i])] = group[0];
                members[size_t(group[0])].push_back(group[i]);
                members[size_t(group[i])].clear();
            }
        std::vector<std::set<int>> succ(n);
        std::vector<int> indeg(n, 0);
        for (size_t k = 0; k < n; ++k)
            for (int from : preds[k]) {
                const int u = unit[size_t(from)], w = unit[k];
                if (u != w && succ[size_t(u)].insert(w).second) ++indeg[size_t(w)];
            }
        std::set<int> ready;
        for (size_t u = 0; u < n; ++u)
            if (!members[u].empty() && indeg[u] == 0) ready.insert(int(u));
        order.clear();
        stepOf.clear();
        steps = 0;
        while (!ready.empty()) {
            const int u = *ready.begin();
            ready.erase(ready.begin());
            for (int k : members[size_t(u)]) {
                order.push_back(g_->order[size_t(k)]);
                stepOf.push_back(steps);
            }
            ++steps;
            for (int w : succ[size_t(u)])
                if (--indeg[size_t(w)] == 0) ready.insert(w);
        }
        return order.size() == n;
    }

    /// Groups executed passes that may run fused (Pass::fusionKey) into steps. Passes of one key
    /// are split into groups none of whose members depends on another (greedily, in execution
    /// order); each group is contracted into one node of the dependency graph, which is sorted
    /// again (contract).
    void fuse() {
        const size_t n = g_->order.size();
        std::vector<int> execIndex(g_->nodes.size(), -1);
        for (size_t k = 0; k < n; ++k) execIndex[size_t(g_->order[k])] = int(k);
        // Same-frame dependencies (through forwarded passes) and their transitive closure;
        // `order` is topological, so every predecessor's ancestors are known first.
        std::vector<std::vector<int>> preds(n);
        std::vector<std::vector<char>> ancestor(n, std::vector<char>(n, 0));
        for (size_t k = 0; k < n; ++k) {
            const int v = g_->order[k];
            const auto& ports = descOf(v).ports;
            for (size_t p = 0; p < ports.size(); ++p) {
                const int e = node(v).inEdge[p];
                if (ports[p].kind != PortKind::Input || e < 0 || edge(e).history) continue;
                const auto src = sourceOf(v, int(p));
                if (!src || execIndex[size_t(src->node)] < 0) continue;
                const int from = execIndex[size_t(src->node)];
                preds[k].push_back(from);
                ancestor[k][size_t(from)] = 1;
                for (size_t a = 0; a < n; ++a) ancestor[k][a] |= ancestor[size_t(from)][a];
            }
        }
        std::map<std::string, std::vector<std::vector<int>>> byKey;  // key -> groups
        const auto consumed = consumedOutputs();
        for (size_t k = 0; k < n; ++k) {
            const std::string key = fusionKeyOf(g_->order[k], consumed);
            if (key.empty()) continue;
            auto& groups = byKey[key];
            auto independent = [&](const std::vector<int>& group) {
                return std::none_of(group.begin(), group.end(),
                                    [&](int m) { return ancestor[k][size_t(m)] != 0; });
            };
            auto it = std::find_if(groups.begin(), groups.end(), independent);
            if (it == groups.end())
                groups.push_back({int(k)});
            else
                it->push_back(int(k));
        }
        std::vector<std::vector<int>> groups;
        for (const auto& [key, keyGroups] : byKey)
            for (const auto& group : keyGroups)
                if (group.size() > 1) groups.push_back(group);
        std::sort(groups.begin(), groups.end());  // by first member: deterministic
        // Two groups can each wait for the other (p -> q and r -> s with {p, s} and {q, r}):
        // then the last group is left out, until the contracted graph sorts.
        std::vector<int> order, stepOf;
        int steps = 0;
        while (!groups.empty() && !contract(groups, preds, order, stepOf, steps)) groups.pop_back();
        if (groups.empty()) return;
        for (const auto& group : groups) {
            std::vector<std::string> names;
            for (int k : group) names.push_back(node(g_->order[size_t(k)]).name);
            g_->report.fused.push_back(std::move(names));
        }
        g_->order = std::move(order);
        g_->stepOf = std::move(stepOf);
        g_->steps = steps;
    }

    void planResources() {
        // Indices are steps: passes fused into one step read and write at the same time.
        std::vector<int> execIndex(g_->nodes.size(), -1);
        for (size_t k = 0; k < g_->order.size(); ++k)
            execIndex[size_t(g_->order[k])] = g_->stepOf[k];
        const int end = g_->steps;
        std::map<std::pair<int, int>, int> resourceOf;  // (node, output port) -> resource
        std::vector<int> producerNode;                  // resource -> node
        auto getResource = [&](PortRef src) {
            auto key = std::make_pair(src.node, src.port);
            auto it = resourceOf.find(key);
            if (it != resourceOf.end()) return it->second;
            const PortDesc& pd = descOf(src.node).ports[size_t(src.port)];
            if (pd.format == Format::Any)
                throw Error("pass '" + node(src.node).name + "' output '" + pd.name +
                            "' has format any and must be forwarded");
            ResourceInfo r;
            r.producer = portName(src);
            r.format = pd.format;
            r.firstUse = r.lastUse = execIndex[size_t(src.node)];
            int id = int(g_->resources.size());
            g_->resources.push_back(r);
            producerNode.push_back(src.node);
            resourceOf[key] = id;
            node(src.node).portResource[size_t(src.port)] = id;
            return id;
        };
        for (int v : g_->order) {
            const auto& ports = descOf(v).ports;
            for (size_t p = 0; p < ports.size(); ++p) {
                if (ports[p].kind != PortKind::Input) continue;
                auto src = sourceOf(v, int(p));
                if (!src || execIndex[size_t(src->node)] < 0) continue;
                int r = getResource(*src);
                bool hist = edge(node(v).inEdge[p]).history;
                node(v).portResource[p] = r;
                node(v).portHistory[p] = hist;
                auto& res = g_->resources[size_t(r)];
                if (hist) {
                    res.history = true;
                    res.lastHistoryRead = std::max(res.lastHistoryRead, execIndex[size_t(v)]);
                } else
                    res.lastUse = std::max(res.lastUse, execIndex[size_t(v)]);
            }
        }
        for (auto& res : g_->resources)
            res.doubleBuffered = res.history && res.lastHistoryRead >= res.firstUse;
        g_->markedResource.clear();
        for (auto [v, p] : g_->marked) {
            int r = getResource({v, p});
            g_->resources[size_t(r)].marked = true;
            g_->resources[size_t(r)].lastUse = end;
            g_->markedResource.push_back(r);
        }
        // Lifetime-based aliasing: walk the execution order, give each transient output the
        // lowest free planes before its pass runs, and free a resource's planes once its last
        // reader has run. Outputs are taken before inputs are freed, so a pass never writes
        // into memory it reads, except in place: an output declared inPlaceOf an input takes
        // over that input's planes when this pass is the input's last reader (the pass is
        // pointwise on the pair). History resources persist across frames; their memory is lent
        // only while idle (IdleHistory).
        std::vector<bool> handedOver(g_->resources.size(), false);
        std::vector<int> stepSize(size_t(end), 0);
        for (int step : g_->stepOf) ++stepSize[size_t(step)];
        // The resource that output resource `r` may be written over (PassDesc::inPlaceOf):
        // the declared input, read this frame through that port only, by a pass in a step of
        // its own (in a fused step the passes run at once, so any may still read it); else -1.
        auto inPlaceInput = [&](int r) -> int {
            const int v = producerNode[size_t(r)];
            if (!options_.inPlace || stepSize[size_t(g_->resources[size_t(r)].firstUse)] != 1)
                return -1;
            const auto& ports = descOf(v).ports;
            const auto& pr = node(v).portResource;
            int out = -1;
            for (size_t p = 0; p < ports.size(); ++p)
                if (ports[p].kind == PortKind::Output && pr[p] == r) out = int(p);
            if (out < 0 || ports[size_t(out)].inPlaceOf.empty()) return -1;
            int in = -1, readers = 0;
            for (size_t p = 0; p < ports.size(); ++p)
                if (ports[p].kind == PortKind::Input &&
                    ports[p].name == ports[size_t(out)].inPlaceOf)
                    in = int(p);
            if (in < 0 || pr[size_t(in)] < 0 || node(v).portHistory[size_t(in)]) return -1;
            const int src = pr[size_t(in)];
            for (size_t p = 0; p < ports.size(); ++p)  // read through this port only
                if (ports[p].kind == PortKind::Input && pr[p] == src) ++readers;
            const auto& s = g_->resources[size_t(src)];
            if (readers != 1 || s.history || s.marked ||
                s.format != g_->resources[size_t(r)].format)
                return -1;
            return src;
        };
        // Transient output r takes over its input's planes when r's pass is the input's last
        // reader and the input holds planes of its own.
        auto inPlaceSource = [&](int k, int r) -> int {
            const int src = inPlaceInput(r);
            if (src < 0) return -1;
            const auto& s = g_->resources[size_t(src)];
            if (s.lastUse != k || !s.historyPlanes.empty() || handedOver[size_t(src)]) return -1;
            return src;
        };
        // A one-buffer history resource written over a transient resource in place (its last
        // reader there) can hold that resource from its first step, when last frame's value is
        // read by then: e.g. the accumulated colour that a blend turns into next frame's
        // history. writtenOver[r]: that history, else -1.
        IdleHistory idleHistory(g_->resources, end);
        const bool lend = options_.historyIdle;
        std::vector<int> writtenOver(g_->resources.size(), -1);
        for (size_t h = 0; h < g_->resources.size() && lend; ++h) {
            const auto& hist = g_->resources[h];
            if (!hist.history || hist.doubleBuffered) continue;
            if (const int src = inPlaceInput(int(h));
                src >= 0 && g_->resources[size_t(src)].lastUse == hist.firstUse)
                writtenOver[size_t(src)] = int(h);
        }
        std::set<int> freePlanes;
        int nextPlane = 0;
        // Idle while step k runs: free after its outputs are placed, before its inputs are
        // released (it still reads them), plus every plane first taken after step k.
        std::vector<std::vector<int>> idle(static_cast<size_t>(end));
        std::vector<int> firstUnused(static_cast<size_t>(end));
        for (int k = 0; k < end; ++k) {
            for (size_t r = 0; r < g_->resources.size(); ++r) {
                auto& res = g_->resources[r];
                if (res.history || res.firstUse != k) continue;
                int need = channelCount(res.format);
                g_->unaliasedPlanes += need;
                if (writtenOver[r] >= 0) {
                    res.historyPlanes = idleHistory.takeWhole(writtenOver[r], k);
                    if (!res.historyPlanes.empty()) continue;
                }
                if (const int src = inPlaceSource(k, int(r)); src >= 0) {
                    res.planes = g_->resources[size_t(src)].planes;
                    res.inPlaceOf = src;
                    handedOver[size_t(src)] = true;
                    continue;
                }
                if (lend && !res.marked) {
                    res.historyPlanes = idleHistory.take(need, k, res.lastUse);
                    if (!res.historyPlanes.empty()) continue;
                }
                for (int c = 0; c < need; ++c) {
                    if (!freePlanes.empty()) {
                        res.planes.push_back(*freePlanes.begin());
                        freePlanes.erase(freePlanes.begin());
                    } else {
                        res.planes.push_back(nextPlane++);
                    }
                }
            }
            idle[size_t(k)].assign(freePlanes.begin(), freePlanes.end());
            firstUnused[size_t(k)] = nextPlane;
            for (size_t r = 0; r < g_->resources.size(); ++r) {
                const auto& res = g_->resources[r];
                if (!res.history && res.historyPlanes.empty() && res.lastUse == k && !handedOver[r])
                    for (int pl : res.planes) freePlanes.insert(pl);
            }
        }
        g_->transientPlanes = nextPlane;
        for (int k = 0; k < end; ++k)
            for (int pl = firstUnused[size_t(k)]; pl < nextPlane; ++pl)
                idle[size_t(k)].push_back(pl);
        g_->idlePlanes = std::move(idle);
    }

    const Registry& registry_;
    CompileOptions options_;
    std::unique_ptr<CompiledGraph::Impl> g_;
    std::vector<Diagnostic> diags_;
    std::map<std::string, int> byName_;
    std::vector<int> rootNodes_;
};

}  // namespace

std::unique_ptr<CompiledGraph> compileGraph(const GraphDesc& graph, const Registry& registry,
                                            const CompileOptions& options) {
    Compiler c(graph, registry, options);
    return std::make_unique<CompiledGraph>(c.run());
}

CompiledGraph::CompiledGraph(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
CompiledGraph::~CompiledGraph() = default;
const GraphDesc& CompiledGraph::desc() const {
    return impl_->desc;
}
const CompileReport& CompiledGraph::report() const {
    return impl_->report;
}
const std::vector<ResourceInfo>& CompiledGraph::resources() const {
    return impl_->resources;
}
int CompiledGraph::transientPlaneCount() const {
    return impl_->transientPlanes;
}
int CompiledGraph::unaliasedPlaneCount() const {
    return impl_->unaliasedPlanes;
}
const std::vector<int>& CompiledGraph::idlePlanes(size_t k) const {
    static const std::vector<int> none;
    if (k >= impl_->stepOf.size()) return none;
    const size_t step = size_t(impl_->stepOf[k]);
    return step < impl_->idlePlanes.size() ? impl_->idlePlanes[step] : none;
}
int CompiledGraph::stepOf(size_t k) const {
    return k < impl_->stepOf.size() ? impl_->stepOf[k] : -1;
}

std::vector<std::string> CompiledGraph::executionOrder() const {
    std::vector<std::string> r;
    for (int v : impl_->order) r.push_back(impl_->nodes[size_t(v)].name);
    return r;
}

std::vector<std::pair<std::string, Pass*>> CompiledGraph::livePasses() const {
    std::vector<std::pair<std::string, Pass*>> r;
    for (int v : impl_->order)
        r.emplace_back(impl_->nodes[size_t(v)].name, impl_->nodes[size_t(v)].pass.get());
    return r;
}

std::vector<std::pair<std::string, Pass*>> CompiledGraph::passesOfType(
    const std::string& type) const {
    std::vector<std::pair<std::string, Pass*>> r;
    for (const auto& n : impl_->nodes)
        if (n.type && n.type->desc.type == type && n.pass) r.emplace_back(n.name, n.pass.get());
    return r;
}

std::vector<std::pair<std::string, Pass*>> CompiledGraph::sinks() const {
    std::vector<std::pair<std::string, Pass*>> r;
    for (int v : impl_->order)
        if (impl_->nodes[size_t(v)].type->desc.sink)
            r.emplace_back(impl_->nodes[size_t(v)].name, impl_->nodes[size_t(v)].pass.get());
    return r;
}

std::string CompiledGraph::provenanceJson() const {
    json passes = json::array();
    for (int v : impl_->order) {
        const auto& n = impl_->nodes[size_t(v)];
        json params = json::object();
        for (const auto& [k, val] : n.params.all()) params[k] = detail::paramValueToJson(val);
        passes.push_back({{"name", n.name}, {"type", n.type->desc.type}, {"params", params}});
    }
    return json{{"graph", impl_->desc.name}, {"passes", passes}}.dump();
}

namespace {
std::string dotEscape(const std::string& s) {
    std::string r;
    for (char c : s) {
        if (c == '"' || c == '\\') r += '\\';
        r += c;
    }
    return r;
}
}  // namespace

std::string CompiledGraph::toDot() const {
    const Impl& g = *impl_;
    std::ostringstream o;
    o << "digraph \"" << dotEscape(g.desc.name) << "\" {\n  rankdir=LR;\n"
      << "  node [shape=box, style=rounded, fontname=\"Helvetica\"];\n";
    std::map<std::string, std::string> leftOut;
    for (const auto& p : g.report.pruned) leftOut[p.pass] = "pruned: " + p.reason;
    for (const auto& p : g.report.elided) leftOut[p.pass] = "left out: " + p.reason;
    std::map<std::string, std::string> fusedWith;  // pass -> the other passes of its step
    for (const auto& step : g.report.fused)
        for (const auto& pass : step)
            for (const auto& other : step)
                if (other != pass) fusedWith[pass] += (fusedWith[pass].empty() ? "" : ", ") + other;
    auto node = [&](const NodeState& n, const std::string& indent) {
        std::string type = n.type ? n.type->desc.type : "?";
        o << indent << "\"" << dotEscape(n.name) << "\" [label=\"" << dotEscape(n.name) << "\\n("
          << type << ")";
        if (auto f = fusedWith.find(n.name); f != fusedWith.end())
            o << "\\nfused with " << dotEscape(f->second);
        auto it = leftOut.find(n.name);
        if (it != leftOut.end())
            o << "\\n"
              << dotEscape(it->second)
              << "\", style=\"rounded,dashed\", color=gray50, fontcolor=gray50];\n";
        else
            o << "\", style=\"rounded,filled\", fillcolor=\"#dde8f5\"];\n";
    };
    // Group instances are clusters (nested instances inside their parent's cluster), each
    // holding the passes expanded from it.
    const auto& instances = g.desc.instances;
    auto parentOf = [&](const std::string& path) {
        std::string parent;
        for (const auto& i : instances)
            if (path.size() > i.path.size() + 1 && path.rfind(i.path + ".", 0) == 0 &&
                i.path.size() > parent.size())
                parent = i.path;
        return parent;
    };
    std::function<void(const std::string&, const std::string&)> cluster =
        [&](const std::string& path, const std::string& indent) {
            for (size_t i = 0; i < g.nodes.size(); ++i)
                if (i < g.desc.passes.size() && g.desc.passes[i].instance == path)
                    node(g.nodes[i], indent);
            for (const auto& inst : instances) {
                if (parentOf(inst.path) != path) continue;
                o << indent << "subgraph \"cluster_" << dotEscape(inst.path) << "\" {\n"
                  << indent << "  label=\"" << dotEscape(inst.path) << " (" << dotEscape(inst.group)
                  << ")\"; style=\"rounded\"; color=\"#7f8c8d\";\n";
                cluster(inst.path, indent + "  ");
                o << indent << "}\n";
            }
        };
    cluster("", "  ");
    for (const auto& e : g.desc.edges) {
        std::string label = dotEscape(e.fromPort + " -> " + e.toPort);
        // Which memory the edge's resource lives in: planes shared by several resources alias.
        auto srcIt = std::find_if(g.nodes.begin(), g.nodes.end(),
                                  [&](const NodeState& n) { return n.name == e.fromPass; });
        if (srcIt != g.nodes.end() && srcIt->type) {
            int p = -1;
            const auto& ports = srcIt->type->desc.ports;
            for (size_t i = 0; i < ports.size(); ++i)
                if (ports[i].name == e.fromPort && ports[i].kind == PortKind::Output) p = int(i);
            if (p >= 0 && srcIt->portResource.size() > size_t(p) &&
                srcIt->portResource[size_t(p)] >= 0) {
                const auto& r = g.resources[size_t(srcIt->portResource[size_t(p)])];
                if (r.history)
                    label += r.doubleBuffered ? "\\n[history, 2 buffers]"
                                              : "\\n[history, 1 buffer: read, then rewritten]";
                else if (!r.historyPlanes.empty()) {
                    label += "\\n[idle history planes";
                    for (const auto& hp : r.historyPlanes)
                        label += " " + dotEscape(g.resources[size_t(hp.resource)].producer) + "/" +
                                 std::to_string(hp.channel);
                    label += "]";
                } else if (!r.planes.empty()) {
                    label += "\\n[mem planes";
                    for (int pl : r.planes) label += " " + std::to_string(pl);
                    label += r.inPlaceOf >= 0 ? ", written in place]" : "]";
                }
            }
        }
        o << "  \"" << dotEscape(e.fromPass) << "\" -> \"" << dotEscape(e.toPass) << "\" [label=\""
          << label << "\"";
        if (e.history)
            o << ", style=dashed, color=\"#c0392b\", fontcolor=\"#c0392b\", constraint=false";
        o << "];\n";
    }
    o << "  label=\"" << dotEscape(g.desc.name) << ": " << g.order.size() << " live passes, "
      << g.transientPlanes << " transient planes for " << g.unaliasedPlanes
      << " without aliasing; dashed red edges carry last frame's value\";\n}\n";
    return o.str();
}

}  // namespace kestrel
