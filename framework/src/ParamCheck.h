#pragma once
// Internal: checks a JSON parameter object against a pass's declarations.
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "kestrel/Error.h"
#include "kestrel/Pass.h"

namespace kestrel::detail {

/// Declared defaults overridden by `params` (a JSON object). Every unknown key, wrong type,
/// out-of-range value or unknown enum choice is appended to `diags` at `path`.params.<key>.
ParamValues checkParams(const PassDesc& desc, const nlohmann::json& params, const std::string& path,
                        std::vector<Diagnostic>& diags);

nlohmann::json paramValueToJson(const ParamValue& v);

/// Edit distance, for "did you mean" suggestions.
size_t editDistance(std::string_view a, std::string_view b);
/// The candidate nearest to `word`, or "" when nothing is reasonably close.
std::string nearestName(std::string_view word, const std::vector<std::string>& candidates);

}  // namespace kestrel::detail
