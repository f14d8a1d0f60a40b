// Compiler phases 3-4: the passes in topological order, then constructed with their parameters.
#include "Compiler.h"

namespace kestrel::compiler {

/// Topological order over same-frame edges; smallest JSON index first among ready passes,
/// so the order is deterministic and follows the file where the graph allows.
void Compiler::order() {
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

void Compiler::construct() {
    for (auto& n : g_->nodes) {
        try {
            n.pass = n.type->create(n.params);
        } catch (const std::exception& e) {
            diags_.push_back({"passes[" + std::to_string(n.jsonIndex) + "]",
                              "pass '" + n.name + "' (" + n.type->desc.type + "): " + e.what()});
        }
    }
}

}  // namespace kestrel::compiler
