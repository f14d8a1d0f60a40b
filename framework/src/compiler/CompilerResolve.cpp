// Compiler phases 5-6: what each input reads (through passes left out), and what is live.
#include "Compiler.h"

namespace kestrel::compiler {

/// The output that really produces what `input` of node `n` reads: follows forwards.
/// nullopt when unconnected or absent (reason in `why`).
std::optional<PortRef> Compiler::sourceOf(int n, int input, std::string* why, std::vector<int>* via,
                                          std::string* root) {
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
                *why = s.absent ? "pass '" + s.name + "' is left out because " + origin : origin;
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

void Compiler::resolve() {
    for (int v : g_->topo) {
        NodeState& n = node(v);
        const auto& ports = descOf(v).ports;
        for (size_t p = 0; p < ports.size(); ++p) {
            if (ports[p].kind != PortKind::Input || ports[p].optional || n.inEdge[p] < 0) continue;
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

void Compiler::markLive() {
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

}  // namespace kestrel::compiler
