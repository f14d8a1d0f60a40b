// Graphs: load (groups and includes expanded), override, mark outputs, validate, compile, and
// what the compiler made of them. The calls are the engine's own, as `kestrel run` makes them.
#include <graphdot/GraphDot.h>
#include <graphpaths/GraphPaths.h>
#include <kestrel/SequenceRunner.h>
#include <pybind11/stl.h>

#include <algorithm>
#include <nlohmann/json.hpp>

#include "Bindings.h"

namespace py = pybind11;

namespace kestrel::python {
namespace {

py::list passRecords(const GraphDesc& g) {
    py::list rows;
    for (const auto& p : g.passes) {
        py::dict row;
        row["name"] = p.name;
        row["type"] = p.type;
        row["instance"] = p.instance;
        row["params"] = fromJson(p.paramsJson);
        rows.append(row);
    }
    return rows;
}

py::list edgeRecords(const GraphDesc& g) {
    py::list rows;
    for (const auto& e : g.edges) {
        py::dict row;
        row["from"] = e.fromPass + "." + e.fromPort;
        row["to"] = e.toPass + "." + e.toPort;
        row["history"] = e.history;
        rows.append(row);
    }
    return rows;
}

/// As `kestrel run GRAPH --input ... --output ... --set ...` prepares it (in that order).
std::shared_ptr<GraphObject> loadGraph(const std::string& path,
                                       const std::vector<std::string>& sets,
                                       const std::vector<std::string>& inputs,
                                       const std::vector<std::string>& outputs) {
    auto g = std::make_shared<GraphObject>();
    g->session = session();
    g->desc = loadGraphFile(path);
    graphpaths::assignInputs(g->desc, g->session->registry, inputs);
    graphpaths::assignOutputs(g->desc, g->session->registry, outputs);
    for (const auto& s : sets) applyOverride(g->desc, s, &g->session->registry);
    g->sets = sets;
    return g;
}

/// Removes a pass with its edges and marked outputs (a writer, to keep results in memory).
void removePass(GraphObject& g, const std::string& name) {
    auto& passes = g.desc.passes;
    auto it = std::find_if(passes.begin(), passes.end(), [&](auto& p) { return p.name == name; });
    if (it == passes.end()) throw Error("remove_pass: the graph has no pass '" + name + "'");
    passes.erase(it);
    std::erase_if(g.desc.edges, [&](auto& e) { return e.fromPass == name || e.toPass == name; });
    std::erase_if(g.desc.outputs,
                  [&](const std::string& o) { return o == name || o.rfind(name + ".", 0) == 0; });
}

std::shared_ptr<CompiledObject> compile(const GraphObject& g, int64_t firstFrame, bool fuse) {
    CompileOptions options;
    options.firstFrame = firstFrame;
    options.fuse = fuse;
    auto c = std::make_shared<CompiledObject>();
    c->session = g.session;
    c->graph = compileGraph(g.desc, g.session->registry, options);
    // An override that reaches only passes this scene leaves out would silently do nothing.
    if (auto unused = unusedOverrides(*c->graph, g.sets, g.session->registry); !unused.empty())
        throw GraphError(std::move(unused));
    return c;
}

py::list leftOut(const CompileReport& r) {
    py::list rows;
    auto add = [&](const LeftOutPass& p, const char* why) {
        py::dict row;
        row["pass"] = p.pass;
        row["why"] = why;
        row["reason"] = p.reason;
        row["for_its_parameters"] = p.forItsParameters;
        rows.append(row);
    };
    for (const auto& p : r.pruned) add(p, "pruned");
    for (const auto& p : r.elided) add(p, "elided");
    return rows;
}

py::list resourceRecords(const CompiledGraph& c) {
    py::list rows;
    for (const auto& r : c.resources()) {
        py::dict row;
        row["producer"] = r.producer;
        row["format"] = std::string(formatName(r.format));
        row["history"] = r.history;
        row["marked"] = r.marked;
        rows.append(row);
    }
    return rows;
}

py::dict portRecord(const PortDesc& p) {
    py::dict row;
    row["name"] = p.name;
    row["kind"] = p.kind == PortKind::Input ? "input" : "output";
    row["format"] = std::string(formatName(p.format));
    row["optional"] = p.optional;
    row["history"] = p.history;
    row["description"] = p.description;
    return row;
}

py::dict paramRecord(const ParamDesc& p) {
    py::dict row;
    row["name"] = p.name;
    row["type"] = std::string(paramTypeName(p.type));
    row["default"] = std::visit([](const auto& v) { return py::cast(v); }, p.defaultValue);
    if (p.type == ParamType::Int || p.type == ParamType::Float) {
        row["min"] = p.min;
        row["max"] = p.max;
    }
    row["choices"] = p.choices;
    row["description"] = p.description;
    return row;
}

/// Every registered pass type, as `kestrel passes` lists them.
py::list passTypes() {
    py::list rows;
    for (const PassType* t : session()->registry.all()) {
        py::dict row;
        row["type"] = t->desc.type;
        row["description"] = t->desc.description;
        row["module"] = t->module;
        py::list ports, params;
        for (const auto& p : t->desc.ports) ports.append(portRecord(p));
        for (const auto& p : t->desc.params) params.append(paramRecord(p));
        row["ports"] = ports;
        row["params"] = params;
        rows.append(row);
    }
    return rows;
}

/// The graph as a Kestrel JSON graph file (overrides applied, history flags and marked outputs
/// kept): `kestrel run` and load_graph read it back as the same graph. A graph with group
/// instances is refused: its passes are named by instance path ("diffuse.atrous0"), which a file
/// cannot declare (a file names the instance and its group); save the file it was loaded from,
/// with its overrides as --set.
std::string graphJson(const GraphDesc& g) {
    if (!g.instances.empty())
        throw Error(
            "to_json: graph '" + g.name + "' has group instances ('" + g.instances.front().path +
            "', ...): write the file it was loaded from and its overrides (Graph.overrides) "
            "as --set instead");
    nlohmann::json passes = nlohmann::json::array(), edges = nlohmann::json::array();
    for (const auto& p : g.passes) {
        nlohmann::json pass = {{"name", p.name}, {"type", p.type}};
        const auto params = nlohmann::json::parse(p.paramsJson.empty() ? "{}" : p.paramsJson);
        if (!params.empty()) pass["params"] = params;
        passes.push_back(std::move(pass));
    }
    for (const auto& e : g.edges) {
        nlohmann::json edge = {{"from", e.fromPass + "." + e.fromPort},
                               {"to", e.toPass + "." + e.toPort}};
        if (e.history) edge["history"] = true;
        edges.push_back(std::move(edge));
    }
    nlohmann::json doc = {{"kestrel", 1}, {"name", g.name}, {"passes", passes}, {"edges", edges}};
    if (!g.outputs.empty()) doc["outputs"] = g.outputs;
    return doc.dump(2) + "\n";
}

/// Falcor's shape: a graph built in code, pass by pass and edge by edge.
std::shared_ptr<GraphObject> emptyGraph(const std::string& name) {
    auto g = std::make_shared<GraphObject>();
    g->session = session();
    g->desc.name = name;
    return g;
}

void createPass(GraphObject& g, const std::string& name, const std::string& type,
                const py::dict& params) {
    for (const auto& p : g.desc.passes)
        if (p.name == name) throw Error("create_pass: the graph has a pass '" + name + "' already");
    PassNode n;
    n.name = name;
    n.type = type;
    n.paramsJson = py::module_::import("json").attr("dumps")(params).cast<std::string>();
    g.desc.passes.push_back(std::move(n));
}

void addEdge(GraphObject& g, const std::string& from, const std::string& to, bool history) {
    EdgeDesc e;
    e.history = history;
    if (!splitPassPort(from, e.fromPass, e.fromPort) || !splitPassPort(to, e.toPass, e.toPort))
        throw Error(std::string(history ? "add_history_edge" : "add_edge") + " " + from + " -> " +
                    to + ": expected 'pass.port' on both sides");
    g.desc.edges.push_back(std::move(e));
}

void bindGraphClass(py::module_& m) {
    py::class_<GraphObject, std::shared_ptr<GraphObject>>(m, "Graph",
                                                          "A parsed graph, groups expanded")
        .def(py::init(&emptyGraph), py::arg("name") = "graph",
             "An empty graph, to build in code (create_pass, add_edge, mark_output)")
        .def("create_pass", &createPass, py::arg("name"), py::arg("type"),
             py::arg("params") = py::dict(), "Adds a pass; checked by validate() and compile()")
        .def(
            "add_edge",
            [](GraphObject& g, const std::string& from, const std::string& to) {
                addEdge(g, from, to, false);
            },
            py::arg("src"), py::arg("dst"), "Connects 'pass.port' to 'pass.port'")
        .def(
            "add_history_edge",
            [](GraphObject& g, const std::string& from, const std::string& to) {
                addEdge(g, from, to, true);
            },
            py::arg("src"), py::arg("dst"), "Feeds last frame's 'pass.port' to 'pass.port'")
        .def_property_readonly("name", [](const GraphObject& g) { return g.desc.name; })
        .def_property_readonly("path",
                               [](const GraphObject& g) { return g.desc.sourcePath.string(); })
        .def_property_readonly("passes", [](const GraphObject& g) { return passRecords(g.desc); })
        .def_property_readonly("edges", [](const GraphObject& g) { return edgeRecords(g.desc); })
        .def_property_readonly("outputs", [](const GraphObject& g) { return g.desc.outputs; })
        .def_property_readonly("overrides", [](const GraphObject& g) { return g.sets; })
        .def(
            "set",
            [](GraphObject& g, const std::string& assignment) {
                auto set = applyOverride(g.desc, assignment, &g.session->registry);
                g.sets.push_back(assignment);
                return set;
            },
            py::arg("assignment"),
            "Applies 'pass.param=value' as --set does (instance path, group parameter or shell "
            "pattern); returns the (pass, parameter) pairs set")
        .def(
            "mark_output",
            [](GraphObject& g, const std::string& passPort) {
                if (std::find(g.desc.outputs.begin(), g.desc.outputs.end(), passPort) ==
                    g.desc.outputs.end())
                    g.desc.outputs.push_back(passPort);
            },
            py::arg("pass_port"), "Keeps 'pass.port' to the end of each frame, readable by a run")
        .def(
            "to_json", [](const GraphObject& g) { return graphJson(g.desc); },
            "The graph as a JSON graph file (groups expanded, overrides applied): save it to run "
            "it with `kestrel run`, or load_graph it back")
        .def("remove_pass", &removePass, py::arg("name"),
             "Removes a pass, its edges and outputs (e.g. the writer, to keep results in memory)")
        .def(
            "validate",
            [](const GraphObject& g) {
                CompileOptions options;
                options.validateOnly = true;
                compileGraph(g.desc, g.session->registry, options);
            },
            "Raises GraphError with every problem `kestrel validate` reports")
        .def("compile", &compile, py::arg("first_frame") = 0, py::arg("fuse") = true,
             "Compiles against the scene its sources read (they open their first frame)");
}

void bindCompiledClass(py::module_& m) {
    py::class_<CompiledObject, std::shared_ptr<CompiledObject>>(m, "CompiledGraph")
        .def_property_readonly("name", [](const CompiledObject& c) { return c.graph->desc().name; })
        .def_property_readonly("execution_order",
                               [](const CompiledObject& c) { return c.graph->executionOrder(); })
        .def_property_readonly("left_out",
                               [](const CompiledObject& c) { return leftOut(c.graph->report()); })
        .def_property_readonly("absent",
                               [](const CompiledObject& c) { return c.graph->report().absent; })
        .def_property_readonly("notes",
                               [](const CompiledObject& c) { return c.graph->report().notes; })
        .def_property_readonly("facts",
                               [](const CompiledObject& c) { return c.graph->report().facts; })
        .def_property_readonly("fused",
                               [](const CompiledObject& c) { return c.graph->report().fused; })
        .def_property_readonly("resources",
                               [](const CompiledObject& c) { return resourceRecords(*c.graph); })
        .def_property_readonly("outputs",
                               [](const CompiledObject& c) { return c.graph->desc().outputs; })
        .def_property_readonly("source_frames",
                               [](const CompiledObject& c) { return sourceFrames(*c.graph); })
        .def(
            "to_dot",
            [](const CompiledObject& c, bool all) {
                return all ? c.graph->toDot() : graphdot::overviewDot(*c.graph);
            },
            py::arg("all") = false,
            "Graphviz DOT as `kestrel graph --dot`: one box per group instance and the live "
            "passes; all=True: every pass, left-out ones dashed with their reasons (--all)")
        .def(
            "to_json", [](const CompiledObject& c) { return c.graph->provenanceJson(); },
            "Compact JSON of the live passes and their effective parameters (provenance)");
}

}  // namespace

void bindGraph(py::module_& m) {
    bindGraphClass(m);
    bindCompiledClass(m);
    m.def("load_graph", &loadGraph, py::arg("path"), py::arg("set") = std::vector<std::string>{},
          py::arg("inputs") = std::vector<std::string>{},
          py::arg("outputs") = std::vector<std::string>{},
          "Reads a JSON graph (groups, includes, extends) and applies --input, --output "
          "(PATTERN or name=PATTERN) and --set-style overrides as `kestrel run` does");
    m.def("pass_types", &passTypes, "Every registered pass type: ports, formats, parameters");
}

}  // namespace kestrel::python
