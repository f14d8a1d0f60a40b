// Compiler phase 7: row-local passes fused into steps that run row by row together.
#include "Compiler.h"

namespace kestrel::compiler {

/// The fusion key of executed node v: its type, fusionKey() and where its fuseOn inputs
/// come from; empty where it cannot fuse.
/// ... and which of its outputs are consumed (`consumed`: node, output port), so that the
/// members of a step produce the same outputs, unless the type fuses members whose outputs
/// differ (FusedOutputs::MayDiffer).
std::string Compiler::fusionKeyOf(int v, const std::set<std::pair<int, int>>& consumed) {
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
std::set<std::pair<int, int>> Compiler::consumedOutputs() {
    std::set<std::pair<int, int>> consumed(g_->marked.begin(), g_->marked.end());
    for (int v : g_->order) {
        const auto& ports = descOf(v).ports;
        for (size_t p = 0; p < ports.size(); ++p)
            if (ports[p].kind == PortKind::Input)
                if (const auto src = sourceOf(v, int(p))) consumed.insert({src->node, src->port});
    }
    return consumed;
}

/// The execution order with each group of `groups` (execution indices) contracted into one
/// step: a topological sort of the contracted dependencies (`preds`), smallest original index
/// first among ready steps. False if the contraction has a cycle.
bool Compiler::contract(const std::vector<std::vector<int>>& groups,
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
void Compiler::fuse() {
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

}  // namespace kestrel::compiler
