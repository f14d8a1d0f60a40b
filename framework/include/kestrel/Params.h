#pragma once
// Declared pass parameters and the values a graph gives them. A pass declares each parameter
// (type, default, range or choices, one-line description) in its PassDesc; the graph compiler
// checks JSON values against the declaration, so a pass only ever reads validated values.
#include <cstdint>
#include <map>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

namespace kestrel {

enum class ParamType { Bool, Int, Float, String, Enum };
std::string_view paramTypeName(ParamType t);

using ParamValue = std::variant<bool, int64_t, double, std::string>;
std::string paramValueToString(const ParamValue& v);

struct ParamDesc {
    std::string name;
    ParamType type = ParamType::Float;
    ParamValue defaultValue;
    double min = -1e300, max = 1e300;  ///< inclusive range for Int and Float
    std::vector<std::string> choices;  ///< for Enum
    std::string description;
};

/// The validated parameter values of one pass instance (declared defaults filled in).
class ParamValues {
public:
    ParamValues() = default;
    explicit ParamValues(std::map<std::string, ParamValue, std::less<>> values)
        : values_(std::move(values)) {}

    bool getBool(std::string_view name) const;
    int64_t getInt(std::string_view name) const;
    float getFloat(std::string_view name) const;
    double getDouble(std::string_view name) const;
    const std::string& getString(std::string_view name) const;  ///< String and Enum
    const ParamValue& get(std::string_view name) const;
    const std::map<std::string, ParamValue, std::less<>>& all() const { return values_; }

private:
    std::map<std::string, ParamValue, std::less<>> values_;
};

}  // namespace kestrel
