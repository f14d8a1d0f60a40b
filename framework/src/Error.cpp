#include "kestrel/Error.h"

namespace kestrel {

namespace {
std::string joinDiagnostics(const std::vector<Diagnostic>& diags) {
    if (diags.empty()) return "invalid graph";
    std::string s = diags.front().str();
    if (diags.size() > 1) s += " (and " + std::to_string(diags.size() - 1) + " more)";
    return s;
}
}  // namespace

GraphError::GraphError(std::vector<Diagnostic> diags)
    : Error(joinDiagnostics(diags)), diags_(std::move(diags)) {}

}  // namespace kestrel
