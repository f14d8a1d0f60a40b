#pragma once
// The engine's error classes as Python exceptions: kestrel.Error and its subclasses GraphError
// (with .diagnostics) and FrameError, carrying the line the CLI prints after "error: ".
#include <pybind11/pybind11.h>

#include <string>

namespace kestrel::python {

/// Creates the exception classes in `m` and translates engine errors into them.
void bindErrors(pybind11::module_& m);

/// Raises kestrel.FrameError (frameError) or kestrel.Error with `message` (a failed run's line).
[[noreturn]] void throwRunError(const std::string& message, bool frameError);

/// Whether a Python exception is a kestrel.FrameError (raised by a pass written in Python).
bool isFrameError(pybind11::error_already_set& e);

}  // namespace kestrel::python
