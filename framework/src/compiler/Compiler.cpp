// The compiler's driver: its phases in order, and the JSON path and pass name of each diagnostic.
#include "Compiler.h"

namespace kestrel::compiler {

std::unique_ptr<CompiledGraph::Impl> Compiler::run() {
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

std::string Compiler::portName(PortRef r) {
    return node(r.node).name + "." + descOf(r.node).ports[size_t(r.port)].name;
}

/// Diagnostics name passes and edges by their index in the flat graph; the user wrote them
/// elsewhere (an instance expands to many passes, a group may live in another file). Each
/// gets the JSON path where it is written, and the pass (parameter) it concerns by name.
std::vector<Diagnostic> Compiler::relocate(std::vector<Diagnostic> diags) const {
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
std::vector<Diagnostic> Compiler::mergeOptionDiagnostics(std::vector<Diagnostic> diags) {
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

}  // namespace kestrel::compiler

namespace kestrel {

std::unique_ptr<CompiledGraph> compileGraph(const GraphDesc& graph, const Registry& registry,
                                            const CompileOptions& options) {
    compiler::Compiler c(graph, registry, options);
    return std::make_unique<CompiledGraph>(c.run());
}

}  // namespace kestrel
