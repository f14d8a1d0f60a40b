#pragma once
// The objects the module hands to Python and the functions that bind each part of the API.
#include <kestrel/Compiler.h>
#include <kestrel/Graph.h>
#include <pybind11/pybind11.h>

#include <atomic>
#include <memory>
#include <string>
#include <vector>

#include "Session.h"

namespace kestrel::python {

/// A parsed graph (groups expanded) and the overrides applied to it, which compile() checks
/// reach a live pass as `kestrel run` does.
struct GraphObject {
    std::shared_ptr<Session> session;
    GraphDesc desc;
    std::vector<std::string> sets;
};

/// A compiled graph. Shared: every run of it holds it (an executor refers to its passes).
struct CompiledObject {
    std::shared_ptr<Session> session;
    std::unique_ptr<CompiledGraph> graph;
    /// Its passes serve one executor at a time: a second run from another thread is refused.
    std::atomic<bool> running{false};
};

void bindGraph(pybind11::module_& m);
void bindRun(pybind11::module_& m);
void bindEval(pybind11::module_& m);
void bindPythonPasses(pybind11::module_& m);
void bindArraySource(pybind11::module_& m);

/// A JSON text as Python objects (json.loads).
pybind11::object fromJson(const std::string& text);

}  // namespace kestrel::python
