#include "PassDecl.h"

#include <pybind11/stl.h>

#include <string>

namespace py = pybind11;

namespace kestrel::python {
namespace {

std::string stringAttr(const py::object& cls, const char* name, const std::string& fallback) {
    return py::hasattr(cls, name) ? py::str(cls.attr(name)).cast<std::string>() : fallback;
}

Format formatOf(const std::string& where, const std::string& name) {
    if (auto f = parseFormat(name)) return *f;
    throw Error(where + ": unknown format '" + name +
                "' (float, float2, float3, float4, int32 or any)");
}

void declarePort(PassDesc& d, const std::string& where, const std::string& name,
                 const py::handle& spec, PortKind kind) {
    py::dict opts = py::isinstance<py::dict>(spec) ? py::reinterpret_borrow<py::dict>(spec)
                                                   : py::dict(py::arg("format") = spec);
    const Format f = formatOf(where + "." + name, py::str(opts["format"]).cast<std::string>());
    const std::string desc = opts.contains("description") ? py::str(opts["description"]) : "";
    auto flag = [&](const char* k) { return opts.contains(k) && opts[k].cast<bool>(); };
    if (kind == PortKind::Output)
        d.output(name, f, desc);
    else if (flag("history"))
        d.historyInput(name, f, desc);
    else if (flag("optional"))
        d.optionalInput(name, f, desc);
    else
        d.input(name, f, desc);
}

void declareParam(PassDesc& d, const std::string& where, const std::string& name,
                  const py::handle& spec) {
    py::dict o = py::isinstance<py::dict>(spec) ? py::reinterpret_borrow<py::dict>(spec)
                                                : py::dict(py::arg("default") = spec);
    if (!o.contains("default")) throw Error(where + "." + name + ": no default");
    py::object def = o["default"];
    const std::string desc = o.contains("description") ? py::str(o["description"]) : "";
    auto bound = [&](const char* k, double v) { return o.contains(k) ? o[k].cast<double>() : v; };
    if (py::isinstance<py::bool_>(def))
        d.paramBool(name, def.cast<bool>(), desc);
    else if (py::isinstance<py::int_>(def))
        d.paramInt(name, def.cast<int64_t>(), int64_t(bound("min", -1e18)),
                   int64_t(bound("max", 1e18)), desc);
    else if (py::isinstance<py::float_>(def))
        d.paramFloat(name, def.cast<double>(), bound("min", -1e300), bound("max", 1e300), desc);
    else if (py::isinstance<py::str>(def) && o.contains("choices"))
        d.paramEnum(name, def.cast<std::string>(), o["choices"].cast<std::vector<std::string>>(),
                    desc);
    else if (py::isinstance<py::str>(def))
        d.paramString(name, def.cast<std::string>(), desc);
    else
        throw Error(where + "." + name + ": a default must be a bool, int, float or str");
}

template <class Fn>
void eachItem(const py::object& cls, const char* attr, Fn&& fn) {
    if (!py::hasattr(cls, attr)) return;
    for (auto [k, v] : py::dict(cls.attr(attr))) fn(py::str(k).cast<std::string>(), v);
}

}  // namespace

PassDesc declarePass(const py::object& cls) {
    const std::string clsName = stringAttr(cls, "__name__", "pass class");
    if (!py::hasattr(cls, "type") || !py::hasattr(cls, "execute"))
        throw Error(clsName + ": a pass class needs a 'type' name and an execute method");
    PassDesc d(stringAttr(cls, "type", ""), stringAttr(cls, "description", clsName));
    const std::string where = clsName;
    eachItem(cls, "inputs", [&](const std::string& n, py::handle s) {
        declarePort(d, where + ".inputs", n, s, PortKind::Input);
    });
    eachItem(cls, "outputs", [&](const std::string& n, py::handle s) {
        declarePort(d, where + ".outputs", n, s, PortKind::Output);
    });
    eachItem(cls, "params",
             [&](const std::string& n, py::handle s) { declareParam(d, where + ".params", n, s); });
    return d;
}

}  // namespace kestrel::python
