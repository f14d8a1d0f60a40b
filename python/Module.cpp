// import kestrel: the engine from Python (docs/python.md).
#include <pybind11/pybind11.h>

#include "Bindings.h"
#include "Errors.h"

namespace kestrel::python {

pybind11::object fromJson(const std::string& text) {
    return pybind11::module_::import("json").attr("loads")(text);
}

}  // namespace kestrel::python

PYBIND11_MODULE(kestrel, m) {
    m.doc() =
        "Kestrel render graphs from Python: load, compile and run graphs, read resources "
        "as numpy arrays, measure errors (docs/python.md).";
    m.attr("__version__") = KESTREL_VERSION;
    kestrel::python::bindErrors(m);
    kestrel::python::bindGraph(m);
    kestrel::python::bindRun(m);
    kestrel::python::bindEval(m);
    kestrel::python::bindPythonPasses(m);
    kestrel::python::bindArraySource(m);
}
