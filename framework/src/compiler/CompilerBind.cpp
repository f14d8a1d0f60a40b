// Compiler phases 1-2: instantiate the passes of the flat graph and bind its edges to ports.
#include "Compiler.h"

namespace kestrel::compiler {

void Compiler::instantiate() {
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
            n.params =
                detail::checkParams(n.type->desc, json::parse(passes[i].paramsJson), path, diags_);
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
int Compiler::findNode(const std::string& name, const std::string& path) {
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

void Compiler::bindEdges() {
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
                diags_.push_back({path + ".from", "pass '" + e.fromPass + "' (" + descOf(s).type +
                                                      ") has no output '" + e.fromPort +
                                                      "' (outputs: " +
                                                      portList(descOf(s), PortKind::Output) + ")"});
        }
        if (d >= 0 && node(d).type) {
            dp = portIndex(descOf(d), e.toPort, PortKind::Input);
            if (dp < 0)
                diags_.push_back({path + ".to", "pass '" + e.toPass + "' (" + descOf(d).type +
                                                    ") has no input '" + e.toPort + "' (inputs: " +
                                                    portList(descOf(d), PortKind::Input) + ")"});
        }
        if (sp < 0 || dp < 0) continue;
        const PortDesc& out = descOf(s).ports[size_t(sp)];
        const PortDesc& in = descOf(d).ports[size_t(dp)];
        if (out.format != Format::Any && !formatAccepts(in.format, out.format))
            diags_.push_back({path, "format mismatch: " + e.fromPass + "." + e.fromPort + " is " +
                                        std::string(formatName(out.format)) + " but " + e.toPass +
                                        "." + e.toPort + " expects " +
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
                                                " is already fed by edges[" + std::to_string(slot) +
                                                "]"});
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

void Compiler::checkOutputs() {
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
            diags_.push_back({path, "pass '" + pass + "' has no output '" + port + "' (outputs: " +
                                        portList(descOf(n), PortKind::Output) + ")"});
            continue;
        }
        g_->marked.push_back({n, p});
        g_->markedNames.push_back(o);
    }
}

}  // namespace kestrel::compiler
