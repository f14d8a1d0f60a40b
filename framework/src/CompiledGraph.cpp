// CompiledGraph: what the compiler made (its accessors), its provenance record and DOT drawing.
#include <cstdio>
#include <nlohmann/json.hpp>
#include <sstream>

#include "CompilerImpl.h"
#include "ParamCheck.h"
#include "kestrel/Compiler.h"

namespace kestrel {

using nlohmann::json;

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
