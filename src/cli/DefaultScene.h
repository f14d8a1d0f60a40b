#pragma once
#include <filesystem>

namespace kestrel::cli {
/// Makes sure the built-in demo scene exists in `dir` (canonical layout, generated once by the
/// scene generator) and returns `dir`.
std::filesystem::path ensureDefaultScene(const std::filesystem::path& dir);
}  // namespace kestrel::cli
