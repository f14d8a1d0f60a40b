#pragma once
// kestrel run --dump PATTERN: every frame of the matching resources (pass.port, or a shell
// pattern such as '*atrous0.color') written as float EXR through the writer's atomic path.
// Each match gets an ExrWriter of its own in the graph, so the compiler keeps the resource alive
// until it is written and the output checks see the files; nothing is added without --dump.
#include <filesystem>
#include <string>
#include <vector>

#include "kestrel/Compiler.h"
#include "kestrel/Graph.h"
#include "kestrel/Registry.h"

namespace kestrel::cli {

/// The "pass.port" resources `compiled` computes, in the order it lists its resources.
std::vector<std::string> computedResources(const CompiledGraph& compiled);

/// Those of computedResources() that the shell pattern matches (none: empty).
std::vector<std::string> matchResources(const CompiledGraph& compiled, const std::string& pattern);

/// The "pass.port" resources of `compiled` that the patterns match, in the order the compiled
/// graph lists its resources. Throws
/// Error naming a pattern that matches nothing (with what there is).
std::vector<std::string> matchDumps(const CompiledGraph& compiled,
                                    const std::vector<std::string>& patterns);

/// Adds a float ExrWriter per resource, writing DIR/pass.port.####.exr.
void addDumpWriters(GraphDesc& graph, const std::vector<std::string>& resources,
                    const std::filesystem::path& dir);

/// --dump-dir's default: dump/ beside the first writer's files (graph order).
std::filesystem::path defaultDumpDir(const GraphDesc& graph, const Registry& registry);

}  // namespace kestrel::cli
