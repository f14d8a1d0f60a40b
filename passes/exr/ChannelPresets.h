#pragma once
// Named presets of the loader's `channels` parameter: other renderers' AOV names (and their
// conventions, where their documentation states them) as channel expressions, so "@arnold"
// stands for the items a user would otherwise type for every output.
#include <string>

namespace kestrel::exr {

/// `spec` with every "@name" item replaced by that preset's items ("?out=EXPR": only where the
/// file has the channels) (later items override earlier
/// ones, so "@arnold,albedo=..." changes one output). Throws Error naming an unknown preset and
/// the known ones.
std::string expandChannelPresets(const std::string& spec);

}  // namespace kestrel::exr
