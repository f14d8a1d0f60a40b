#include "kestrel/Pass.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>

#include "ParamCheck.h"
#include "kestrel/Conventions.h"

namespace kestrel {

float depthPrecision(ResolveContext& rc) {
    const auto r = rc.fact(kDepthPrecisionFact);
    if (!r) return 0.f;
    const float step = std::strtof(r->c_str(), nullptr);
    const float clamped = step == step ? std::clamp(step, 0.f, 1.f) : 0.f;
    rc.note("depth stored with a relative step of " + *r + ": depth tolerance widened");
    return clamped;
}

PassDesc& PassDesc::input(std::string name, Format f, std::string desc) {
    ports.push_back({std::move(name), PortKind::Input, f, false, false, std::move(desc), {}});
    return *this;
}
PassDesc& PassDesc::optionalInput(std::string name, Format f, std::string desc) {
    ports.push_back({std::move(name), PortKind::Input, f, true, false, std::move(desc), {}});
    return *this;
}
PassDesc& PassDesc::historyInput(std::string name, Format f, std::string desc) {
    ports.push_back({std::move(name), PortKind::Input, f, true, true, std::move(desc), {}});
    return *this;
}
PassDesc& PassDesc::output(std::string name, Format f, std::string desc) {
    ports.push_back({std::move(name), PortKind::Output, f, false, false, std::move(desc), {}});
    return *this;
}
PassDesc& PassDesc::inPlaceOf(std::string input) {
    if (ports.empty() || ports.back().kind != PortKind::Output)
        throw Error("pass type '" + type + "': inPlaceOf('" + input + "') must follow an output");
    const PortDesc* in = nullptr;
    for (const auto& p : ports)
        if (p.kind == PortKind::Input && p.name == input) in = &p;
    if (!in || in->history || in->format != ports.back().format)
        throw Error("pass type '" + type + "': output '" + ports.back().name +
                    "' cannot be in place of '" + input +
                    "': that must be a this-frame input declared before it, of the same format");
    ports.back().inPlaceOf = std::move(input);
    return *this;
}

PassDesc& PassDesc::fuseOn(std::vector<std::string> inputs, FusedOutputs outputs) {
    for (const auto& name : inputs) {
        const PortDesc* in = findPort(name);
        if (!in || in->kind != PortKind::Input)
            throw Error("pass type '" + type + "': fuseOn('" + name +
                        "') must name an input declared before it");
    }
    fusedInputs = std::move(inputs);
    fusedOutputsMayDiffer = outputs == FusedOutputs::MayDiffer;
    return *this;
}

void Pass::executeFused(FrameContext& ctx, std::span<Pass* const> passes,
                        std::span<PassIO* const> ios) {
    for (size_t i = 0; i < passes.size(); ++i) passes[i]->execute(ctx, *ios[i]);
}

PassDesc& PassDesc::paramFloat(std::string name, double def, double min, double max,
                               std::string desc) {
    params.push_back({std::move(name), ParamType::Float, def, min, max, {}, std::move(desc)});
    return *this;
}
PassDesc& PassDesc::paramInt(std::string name, int64_t def, int64_t min, int64_t max,
                             std::string desc) {
    params.push_back(
        {std::move(name), ParamType::Int, def, double(min), double(max), {}, std::move(desc)});
    return *this;
}
PassDesc& PassDesc::paramBool(std::string name, bool def, std::string desc) {
    params.push_back({std::move(name), ParamType::Bool, def, 0, 1, {}, std::move(desc)});
    return *this;
}
PassDesc& PassDesc::paramString(std::string name, std::string def, std::string desc) {
    params.push_back(
        {std::move(name), ParamType::String, std::move(def), 0, 0, {}, std::move(desc)});
    return *this;
}
PassDesc& PassDesc::paramEnum(std::string name, std::string def, std::vector<std::string> choices,
                              std::string desc) {
    params.push_back({std::move(name), ParamType::Enum, std::move(def), 0, 0, std::move(choices),
                      std::move(desc)});
    return *this;
}

const PortDesc* PassDesc::findPort(std::string_view name) const {
    for (const auto& p : ports)
        if (p.name == name) return &p;
    return nullptr;
}
const ParamDesc* PassDesc::findParam(std::string_view name) const {
    for (const auto& p : params)
        if (p.name == name) return &p;
    return nullptr;
}

namespace detail {

size_t editDistance(std::string_view a, std::string_view b) {
    std::vector<size_t> prev(b.size() + 1), cur(b.size() + 1);
    for (size_t j = 0; j <= b.size(); ++j) prev[j] = j;
    for (size_t i = 1; i <= a.size(); ++i) {
        cur[0] = i;
        for (size_t j = 1; j <= b.size(); ++j) {
            size_t sub = prev[j - 1] + (std::tolower(a[i - 1]) == std::tolower(b[j - 1]) ? 0 : 1);
            cur[j] = std::min({prev[j] + 1, cur[j - 1] + 1, sub});
        }
        std::swap(prev, cur);
    }
    return prev[b.size()];
}

std::string nearestName(std::string_view word, const std::vector<std::string>& candidates) {
    std::string best;
    size_t bestD = SIZE_MAX;
    for (const auto& c : candidates) {
        size_t d = editDistance(word, c);
        if (d < bestD) bestD = d, best = c;
    }
    // Only suggest when the names are plausibly the same word.
    if (best.empty() || bestD > std::max<size_t>(2, word.size() / 2)) return {};
    return best;
}

nlohmann::json paramValueToJson(const ParamValue& v) {
    return std::visit([](const auto& x) { return nlohmann::json(x); }, v);
}

namespace {
std::string jsonTypeName(const nlohmann::json& j) {
    return std::string(j.type_name());
}

// Range bounds as a user writes them: "[0, 1]", not "[0.0, 1.0]".
std::string fmtNum(double d) {
    if (std::isfinite(d) && d == std::floor(d) && std::fabs(d) < 1e15)
        return std::to_string(int64_t(d));
    return nlohmann::json(d).dump();
}
}  // namespace

ParamValues checkParams(const PassDesc& desc, const nlohmann::json& params, const std::string& path,
                        std::vector<Diagnostic>& diags) {
    std::map<std::string, ParamValue, std::less<>> values;
    for (const auto& p : desc.params) values[p.name] = p.defaultValue;
    if (params.is_null()) return ParamValues(std::move(values));
    if (!params.is_object()) {
        diags.push_back(
            {path + ".params", "expected an object of parameters, got " + jsonTypeName(params)});
        return ParamValues(std::move(values));
    }
    std::vector<std::string> names;
    for (const auto& p : desc.params) names.push_back(p.name);
    for (const auto& [key, val] : params.items()) {
        std::string where = path + ".params." + key;
        const ParamDesc* pd = desc.findParam(key);
        if (!pd) {
            std::string msg = "unknown parameter '" + key + "' for pass type " + desc.type;
            std::string near = nearestName(key, names);
            if (!near.empty()) msg += " (did you mean '" + near + "'?)";
            if (names.empty()) msg += " (it takes no parameters)";
            diags.push_back({where, msg});
            continue;
        }
        switch (pd->type) {
            case ParamType::Bool:
                if (!val.is_boolean()) {
                    diags.push_back({where, "expected bool, got " + val.dump()});
                    continue;
                }
                values[key] = val.get<bool>();
                break;
            case ParamType::Int: {
                bool integral = val.is_number_integer() ||
                                (val.is_number_float() && std::isfinite(val.get<double>()) &&
                                 val.get<double>() == std::floor(val.get<double>()));
                if (!integral) {
                    diags.push_back({where, "expected integer in [" + fmtNum(pd->min) + ", " +
                                                fmtNum(pd->max) + "], got " + val.dump()});
                    continue;
                }
                double d = val.get<double>();
                if (d < pd->min || d > pd->max) {
                    diags.push_back({where, "expected integer in [" + fmtNum(pd->min) + ", " +
                                                fmtNum(pd->max) + "], got " + val.dump()});
                    continue;
                }
                values[key] = int64_t(d);
                break;
            }
            case ParamType::Float: {
                if (!val.is_number() || !std::isfinite(val.get<double>()) ||
                    val.get<double>() < pd->min || val.get<double>() > pd->max) {
                    diags.push_back({where, "expected number in [" + fmtNum(pd->min) + ", " +
                                                fmtNum(pd->max) + "], got " + val.dump()});
                    continue;
                }
                values[key] = val.get<double>();
                break;
            }
            case ParamType::String:
                if (!val.is_string()) {
                    diags.push_back({where, "expected string, got " + val.dump()});
                    continue;
                }
                values[key] = val.get<std::string>();
                break;
            case ParamType::Enum: {
                std::string choices;
                for (const auto& c : pd->choices) choices += (choices.empty() ? "" : "|") + c;
                // A choice spelled as a JSON scalar (--set 'input.antiAliased=true' parses as
                // the boolean) is the same choice.
                const std::string text = val.is_string() ? val.get<std::string>()
                                         : val.is_boolean() || val.is_number() ? val.dump()
                                                                               : std::string();
                if (text.empty() ||
                    std::find(pd->choices.begin(), pd->choices.end(), text) == pd->choices.end()) {
                    diags.push_back({where, "expected one of " + choices + ", got " + val.dump()});
                    continue;
                }
                values[key] = text;
                break;
            }
        }
    }
    return ParamValues(std::move(values));
}

}  // namespace detail
}  // namespace kestrel
