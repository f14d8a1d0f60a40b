#pragma once
// A pass type's declaration read from a Python class's attributes:
//   type = "Gain"; description = "..."
//   inputs  = {"color": "float3", "prev": {"format": "float3", "history": True}}
//   outputs = {"color": "float3"}
//   params  = {"gain": {"default": 1.0, "min": 0.0, "max": 8.0, "description": "..."},
//              "mode": {"default": "a", "choices": ["a", "b"]}, "on": True}
// A parameter's type is its default's (bool, int, float, str; str with choices: an enum).
#include <kestrel/Pass.h>
#include <pybind11/pybind11.h>

namespace kestrel::python {

/// Throws kestrel::Error naming the class and attribute for a declaration the engine refuses.
PassDesc declarePass(const pybind11::object& cls);

}  // namespace kestrel::python
