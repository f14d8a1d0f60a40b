#pragma once
// The graph compiler (private to the framework): a GraphDesc becomes a CompiledGraph in phases,
// each in its own file beside this one (docs/design.md section 3).
// - Compiler.cpp: the driver (run), and each diagnostic's JSON path and pass name.
// - CompilerBind.cpp: instantiate the passes, bind the edges to ports, check the outputs.
// - CompilerOrder.cpp: order the passes by same-frame edges; construct them with parameters.
// - CompilerResolve.cpp: what each input reads (through passes left out); what is live.
// - CompilerFusion.cpp: row-local passes fused into steps.
// - CompilerResources.cpp: lifetimes, transient planes aliased by lifetime, history buffers.
// CompiledGraph.cpp (one folder up) holds what the compiler made: accessors, provenance, DOT.
#include <algorithm>
#include <cstdio>
#include <functional>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <numeric>
#include <optional>
#include <set>
#include <sstream>
#include <string>
#include <string_view>
#include <vector>

#include "../CompilerImpl.h"
#include "../ParamCheck.h"
#include "kestrel/Compiler.h"

namespace kestrel::compiler {

using nlohmann::json;

struct PortRef {
    int node = -1, port = -1;
    bool operator==(const PortRef&) const = default;
};

inline std::string portList(const PassDesc& d, PortKind kind) {
    std::string s;
    for (const auto& p : d.ports)
        if (p.kind == kind) s += (s.empty() ? "" : ", ") + p.name;
    return s.empty() ? "none" : s;
}

inline int portIndex(const PassDesc& d, std::string_view name, PortKind kind) {
    for (size_t i = 0; i < d.ports.size(); ++i)
        if (d.ports[i].name == name && d.ports[i].kind == kind) return int(i);
    return -1;
}

class Compiler {
public:
    Compiler(const GraphDesc& desc, const Registry& registry, const CompileOptions& options)
        : registry_(registry), options_(options), g_(std::make_unique<CompiledGraph::Impl>()) {
        g_->desc = desc;
    }

    std::unique_ptr<CompiledGraph::Impl> run();

private:
    NodeState& node(int i) { return g_->nodes[size_t(i)]; }
    const PassDesc& descOf(int i) { return node(i).type->desc; }
    const EdgeDesc& edge(int e) { return g_->desc.edges[size_t(e)]; }
    std::string portName(PortRef r);

    /// Diagnostics name passes and edges by their index in the flat graph; the user wrote them
    /// elsewhere (an instance expands to many passes, a group may live in another file). Each
    /// gets the JSON path where it is written, and the pass (parameter) it concerns by name.
    std::vector<Diagnostic> relocate(std::vector<Diagnostic> diags) const;

    /// One line per command-line mistake: a group parameter set out of range drives several
    /// inner parameters, each refusing the same value ("--set single.sigmaLWide=-1
    /// (single.atrous2.sigmaL, single.atrous3.sigmaL, ...)").
    static std::vector<Diagnostic> mergeOptionDiagnostics(std::vector<Diagnostic> diags);

    void instantiate();

    /// The node named `name`; else a diagnostic at `path` (the full JSON path) and -1.
    int findNode(const std::string& name, const std::string& path);

    void bindEdges();

    void checkOutputs();

    /// Topological order over same-frame edges; smallest JSON index first among ready passes,
    /// so the order is deterministic and follows the file where the graph allows.
    void order();

    void construct();

    /// The output that really produces what `input` of node `n` reads: follows forwards.
    /// nullopt when unconnected or absent (reason in `why`).
    std::optional<PortRef> sourceOf(int n, int input, std::string* why = nullptr,
                                    std::vector<int>* via = nullptr, std::string* root = nullptr);

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

    void resolve();

    void markLive();

    /// The fusion key of executed node v: its type, fusionKey() and where its fuseOn inputs
    /// come from; empty where it cannot fuse.
    /// ... and which of its outputs are consumed (`consumed`: node, output port), so that the
    /// members of a step produce the same outputs, unless the type fuses members whose outputs
    /// differ (FusedOutputs::MayDiffer).
    std::string fusionKeyOf(int v, const std::set<std::pair<int, int>>& consumed);

    /// The outputs of executed passes that something reads (this frame or the next) or marks.
    std::set<std::pair<int, int>> consumedOutputs();

    /// The execution order with each group of `groups` (execution indices) contracted into one
    /// step: a topological sort of the contracted dependencies (`preds`), smallest original index
    /// first among ready steps. False if the contraction has a cycle.
    bool contract(const std::vector<std::vector<int>>& groups,
                  const std::vector<std::vector<int>>& preds, std::vector<int>& order,
                  std::vector<int>& stepOf, int& steps);

    /// Groups executed passes that may run fused (Pass::fusionKey) into steps. Passes of one key
    /// are split into groups none of whose members depends on another (greedily, in execution
    /// order); each group is contracted into one node of the dependency graph, which is sorted
    /// again (contract).
    void fuse();

    void planResources();

    const Registry& registry_;
    CompileOptions options_;
    std::unique_ptr<CompiledGraph::Impl> g_;
    std::vector<Diagnostic> diags_;
    std::map<std::string, int> byName_;
    std::vector<int> rootNodes_;
};

}  // namespace kestrel::compiler
