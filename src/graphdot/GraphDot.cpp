#include "graphdot/GraphDot.h"

#include <functional>
#include <map>
#include <set>
#include <sstream>

namespace kestrel::graphdot {

namespace {

std::string escape(const std::string& s) {
    std::string r;
    for (char c : s) {
        if (c == '"' || c == '\\') r += '\\';
        r += c;
    }
    return r;
}

/// The outermost group instance `pass` comes from ("diffuse" for "diffuse.atrous0"), else "".
std::string topInstance(const GraphDesc& g, const std::string& pass) {
    std::string top;
    for (const auto& i : g.instances)
        if (pass.rfind(i.path + ".", 0) == 0 && (top.empty() || i.path.size() < top.size()))
            top = i.path;
    return top;
}

struct Box {
    std::string label;
    int passes = 0;
};

}  // namespace

std::string overviewDot(const CompiledGraph& compiled) {
    const GraphDesc& g = compiled.desc();
    const auto order = compiled.executionOrder();
    const std::set<std::string> live(order.begin(), order.end());

    // Node of each live pass: its top-level instance, or itself.
    std::map<std::string, std::string> nodeOf;
    std::map<std::string, Box> boxes;  // node -> label, live passes in it
    std::vector<std::string> nodeOrder;
    for (const auto& p : g.passes) {
        if (!live.count(p.name)) continue;
        const std::string inst = topInstance(g, p.name);
        const std::string node = inst.empty() ? p.name : inst;
        nodeOf[p.name] = node;
        if (!boxes.count(node)) nodeOrder.push_back(node);
        Box& b = boxes[node];
        ++b.passes;
        if (inst.empty()) {
            b.label = escape(p.name) + "\\n(" + escape(p.type) + ")";
        } else {
            for (const auto& i : g.instances)
                if (i.path == inst) b.label = escape(inst) + "\\n(group " + escape(i.group) + ")";
        }
    }

    std::ostringstream o;
    o << "digraph \"" << escape(g.name) << "\" {\n  rankdir=LR;\n"
      << "  node [shape=box, style=\"rounded,filled\", fillcolor=\"#dde8f5\", "
         "fontname=\"Helvetica\"];\n";
    for (const auto& n : nodeOrder) {
        const Box& b = boxes[n];
        o << "  \"" << escape(n) << "\" [label=\"" << b.label;  // escaped when built
        if (b.label.find("(group ") != std::string::npos)
            o << ", " << b.passes << " passes\", penwidth=2];\n";
        else
            o << "\"];\n";
    }
    // Edges between nodes (not inside one), merged: one arrow per pair and kind. A left-out pass
    // that forwards an input (identity for this scene) is looked through to the live passes
    // feeding it, so the picture stays connected.
    std::set<std::string> elided, absent;  // absent: "pass.port" outputs this scene lacks
    for (const auto& p : compiled.report().elided) elided.insert(p.pass);
    for (const auto& a : compiled.report().absent) absent.insert(a.substr(0, a.find(':')));
    std::map<std::tuple<std::string, std::string, bool>, std::set<std::string>> edges;
    std::function<void(const std::string&, const std::string&, const std::string&, bool, int)>
        connect = [&](const std::string& fromPass, const std::string& fromPort,
                      const std::string& to, bool history, int depth) {
            if (absent.count(fromPass + "." + fromPort)) return;  // no data: no arrow
            if (auto from = nodeOf.find(fromPass); from != nodeOf.end()) {
                if (from->second != to)
                    edges[{from->second, to, history}].insert(fromPass + "." + fromPort);
                return;
            }
            if (!elided.count(fromPass) || depth > 32) return;
            for (const auto& e : g.edges)
                if (e.toPass == fromPass && !e.history)
                    connect(e.fromPass, e.fromPort, to, history, depth + 1);
        };
    for (const auto& e : g.edges)
        if (auto to = nodeOf.find(e.toPass); to != nodeOf.end())
            connect(e.fromPass, e.fromPort, to->second, e.history, 0);
    for (const auto& [key, ports] : edges) {
        const auto& [from, to, history] = key;
        std::string label;
        if (ports.size() <= 2)
            for (const auto& p : ports) label += (label.empty() ? "" : "\\n") + escape(p);
        else
            label = std::to_string(ports.size()) + " outputs";
        o << "  \"" << escape(from) << "\" -> \"" << escape(to) << "\" [label=\"" << label << "\"";
        if (history)
            o << ", style=dashed, color=\"#c0392b\", fontcolor=\"#c0392b\", constraint=false";
        o << "];\n";
    }
    const size_t leftOut = g.passes.size() - live.size();
    o << "  label=\"" << escape(g.name) << ": " << live.size() << " live passes in "
      << nodeOrder.size() << " boxes (a group instance is one box); " << leftOut
      << " passes left out for this scene are hidden (kestrel graph --dot --all shows every "
         "pass); dashed red edges carry last frame's value\";\n}\n";
    return o.str();
}

}  // namespace kestrel::graphdot
