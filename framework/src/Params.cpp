#include "kestrel/Params.h"

#include <sstream>

#include "kestrel/Error.h"

namespace kestrel {

std::string_view paramTypeName(ParamType t) {
    switch (t) {
        case ParamType::Bool: return "bool";
        case ParamType::Int: return "int";
        case ParamType::Float: return "float";
        case ParamType::String: return "string";
        case ParamType::Enum: return "enum";
    }
    return "?";
}

std::string paramValueToString(const ParamValue& v) {
    struct Visitor {
        std::string operator()(bool b) const { return b ? "true" : "false"; }
        std::string operator()(int64_t i) const { return std::to_string(i); }
        std::string operator()(double d) const {
            std::ostringstream s;
            s << d;
            return s.str();
        }
        std::string operator()(const std::string& s) const { return "\"" + s + "\""; }
    };
    return std::visit(Visitor{}, v);
}

const ParamValue& ParamValues::get(std::string_view name) const {
    auto it = values_.find(name);
    if (it == values_.end())
        throw Error("parameter '" + std::string(name) + "' is not declared by this pass");
    return it->second;
}

bool ParamValues::getBool(std::string_view name) const {
    const auto& v = get(name);
    if (auto b = std::get_if<bool>(&v)) return *b;
    throw Error("parameter '" + std::string(name) + "' is not a bool");
}

int64_t ParamValues::getInt(std::string_view name) const {
    const auto& v = get(name);
    if (auto i = std::get_if<int64_t>(&v)) return *i;
    if (auto d = std::get_if<double>(&v)) return int64_t(*d);
    throw Error("parameter '" + std::string(name) + "' is not an integer");
}

double ParamValues::getDouble(std::string_view name) const {
    const auto& v = get(name);
    if (auto d = std::get_if<double>(&v)) return *d;
    if (auto i = std::get_if<int64_t>(&v)) return double(*i);
    throw Error("parameter '" + std::string(name) + "' is not a number");
}

float ParamValues::getFloat(std::string_view name) const { return float(getDouble(name)); }

const std::string& ParamValues::getString(std::string_view name) const {
    const auto& v = get(name);
    if (auto s = std::get_if<std::string>(&v)) return *s;
    throw Error("parameter '" + std::string(name) + "' is not a string");
}

}  // namespace kestrel
