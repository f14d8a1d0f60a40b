#pragma once
// The compile report as a person reads it at default verbosity: a few lines (what the scene
// provides and how passes adapted, grouped; how many passes were left out and for lack of
// what), every detail still available with -v.
#include <string>
#include <vector>

#include "kestrel/Compiler.h"

namespace kestrel::cli {

/// The adaptation notes ("pass: message") grouped: a message several passes share is one line
/// naming them; the messages of a pass no other pass shares are one line for that pass.
std::vector<std::string> groupNotes(const std::vector<std::string>& notes);

/// One line: how many passes were left out and the absent inputs that caused it ("" if none).
std::string leftOutSummary(const CompileReport& report);

}  // namespace kestrel::cli
