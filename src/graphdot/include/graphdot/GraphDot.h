#pragma once
// `kestrel graph --dot` without --all: the compiled graph as a reader wants it first, one box
// per group instance and only the passes this scene runs, so a shipped graph fits a screen.
// --all gives CompiledGraph::toDot (every pass, left-out ones dashed with their reasons).
#include <string>

#include "kestrel/Compiler.h"

namespace kestrel::graphdot {

/// Graphviz DOT of the live passes, each top-level group instance collapsed into one node.
std::string overviewDot(const CompiledGraph& compiled);

}  // namespace kestrel::graphdot
