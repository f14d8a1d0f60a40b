// Parameters at the ends of their ranges (docs/design.md section 8: alpha 0 and 1, sigma tiny and
// huge, A-Trous steps larger than the image...). Enumerated from the registry's declarations, so
// a parameter added later is covered too: for every pass type in the graph, every Float/Int
// parameter is set to its declared minimum and maximum (every choice for Enum, both values for
// Bool) on all passes of that type; each setting must give finite output within the input range.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <limits>
#include <set>
#include <sstream>

#include "Checks.h"

namespace stability {
namespace {

std::string jsonNumber(double v, bool integer) {
    std::ostringstream s;
    if (integer)
        s << int64_t(v);
    else {
        s.precision(17);
        s << v;
    }
    return s.str();
}

/// Every ("type", "param", json value) setting at an end of a declared range.
std::vector<std::array<std::string, 3>> endSettings(const TestGraph& g) {
    std::set<std::string> types;
    for (const auto& p : g.desc.passes)
        if (p.type != "StabilitySource") types.insert(p.type);
    std::vector<std::array<std::string, 3>> out;
    for (const auto& type : types) {
        const kestrel::PassType* t = registry().find(type);
        if (!t) continue;
        for (const auto& p : t->desc.params) {
            switch (p.type) {
                case kestrel::ParamType::Float:
                case kestrel::ParamType::Int: {
                    const bool integer = p.type == kestrel::ParamType::Int;
                    // Ranges are declared; an undeclared (+-1e300) end is out of scope.
                    for (double v : {p.min, p.max})
                        if (std::fabs(v) < 1e30)
                            out.push_back({type, p.name, jsonNumber(v, integer)});
                    break;
                }
                case kestrel::ParamType::Enum:
                    for (const auto& c : p.choices) out.push_back({type, p.name, "\"" + c + "\""});
                    break;
                case kestrel::ParamType::Bool:
                    out.push_back({type, p.name, "true"});
                    out.push_back({type, p.name, "false"});
                    break;
                case kestrel::ParamType::String:
                    break;
            }
        }
    }
    return out;
}

void runAllEnds(const char* graph) {
    // Plain scene with one NaN pixel per frame: the sanitising paths run at every setting.
    const std::string scenario = std::string("ends-") + graph;
    setScenario(scenario, plainScene({48, 32}, [](int64_t, Frame& f) {
                    f["color"].at(0, 9, 9) = std::numeric_limits<float>::quiet_NaN();
                }));
    const TestGraph base = std::string(graph) == "svgf" ? svgfGraph(scenario) : jbfGraph(scenario);
    const auto settings = endSettings(base);
    EXPECT_GT(settings.size(), 10u);
    for (const auto& [type, param, value] : settings) {
        SCOPED_TRACE(std::string(graph) + ": every " + type + "." + param + " = " + value);
        TestGraph g = base;
        ASSERT_GT(setParamOnType(g, type, param, value), 0);
        // Demodulate and Modulate must share their albedo floor (a mismatch rescales the image
        // by design): their ends are tried on both together.
        if (param == "albedoFloor")
            for (const char* t : {"Demodulate", "Modulate"}) setParamOnType(g, t, param, value);
        runBounded(g, 6, 0.f, kPlainHi, 1, type + "." + param + "=" + value);
    }
    std::printf("%s: %zu parameter-end settings run\n", graph, settings.size());
}

TEST(ParameterEnds, SvgfEveryParameterAtBothEndsOfItsRange) {
    runAllEnds("svgf");
}

TEST(ParameterEnds, Games202EveryParameterAtBothEndsOfItsRange) {
    runAllEnds("jbf");
}

}  // namespace
}  // namespace stability
