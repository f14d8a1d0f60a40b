#include "Errors.h"

#include <kestrel/Error.h>

namespace py = pybind11;

namespace kestrel::python {
namespace {

// Created once at import; owned by the module (never freed: the interpreter holds them).
PyObject* gError = nullptr;
PyObject* gGraphError = nullptr;
PyObject* gFrameError = nullptr;

PyObject* newClass(py::module_& m, const char* name, PyObject* base, const char* doc) {
    const std::string qualified = std::string("kestrel.") + name;
    PyObject* cls = PyErr_NewExceptionWithDoc(qualified.c_str(), doc, base, nullptr);
    if (!cls) throw py::error_already_set();
    m.add_object(name, py::handle(cls));
    return cls;
}

/// Every diagnostic on its own line, as the CLI prints them (without its "error: " prefix).
std::string diagnosticLines(const GraphError& e) {
    std::string text;
    for (const auto& d : e.diagnostics()) text += (text.empty() ? "" : "\n") + d.str();
    return text.empty() ? std::string(e.what()) : text;
}

void raiseGraphError(const GraphError& e) {
    py::list diags;
    for (const auto& d : e.diagnostics()) {
        py::dict row;
        row["path"] = d.path;
        row["label"] = d.label;
        row["message"] = d.message;
        row["line"] = d.str();
        diags.append(row);
    }
    py::object exc = py::reinterpret_steal<py::object>(
        PyObject_CallFunction(gGraphError, "s", diagnosticLines(e).c_str()));
    if (!exc) throw py::error_already_set();
    exc.attr("diagnostics") = diags;
    PyErr_SetObject(gGraphError, exc.ptr());
}

}  // namespace

void bindErrors(py::module_& m) {
    gError = newClass(m, "Error", PyExc_RuntimeError,
                      "An engine error; str() is the line `kestrel` prints after 'error: '.");
    gGraphError = newClass(m, "GraphError", gError,
                           "Validation findings; .diagnostics lists each (path, label, message, "
                           "line), str() has one line per finding.");
    gFrameError = newClass(m, "FrameError", gError,
                           "A problem confined to one frame (a missing or corrupt input file).");
    py::register_exception_translator([](std::exception_ptr p) {
        try {
            if (p) std::rethrow_exception(p);
        } catch (const GraphError& e) {
            raiseGraphError(e);
        } catch (const FrameError& e) {
            PyErr_SetString(gFrameError, e.what());
        } catch (const Error& e) {
            PyErr_SetString(gError, e.what());
        }
    });
}

bool isFrameError(py::error_already_set& e) {
    return e.matches(gFrameError);
}

void throwRunError(const std::string& message, bool frameError) {
    PyErr_SetString(frameError ? gFrameError : gError, message.c_str());
    throw py::error_already_set();
}

}  // namespace kestrel::python
