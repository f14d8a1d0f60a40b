#pragma once
// The files a graph reads and writes, as the user names them: `--input PATTERN` (or
// name=PATTERN) sets the path of the graph's file source, `--output` its writer's. Shared by the
// CLI and the Python module (load_graph's inputs= and outputs=), so both give the same messages.
#include <kestrel/Graph.h>
#include <kestrel/Registry.h>

#include <string>
#include <vector>

namespace kestrel::graphpaths {

/// A pass type with no inputs (a source: its time is reported apart from the filter's).
bool isSourceType(const PassType& t);
/// A source reading files: no inputs and a "path" parameter (what --input sets).
bool isSource(const PassType& t);
/// A sink writing files: declared a sink with a "path" parameter (what --output sets).
bool isSink(const PassType& t);

/// The "path" parameter a pass is given in the graph ("" when none).
std::string pathParam(const PassNode& n);

/// Applies each "PATTERN" or "name=PATTERN" to the path of the matching file source (--input)
/// or writer (--output); a bare PATTERN needs the graph to have exactly one. Throws Error naming
/// the option as typed.
void assignInputs(GraphDesc& g, const Registry& reg, const std::vector<std::string>& specs);
void assignOutputs(GraphDesc& g, const Registry& reg, const std::vector<std::string>& specs);

/// The path pattern of the graph's first file source ("" when none has one).
std::string sourcePath(const GraphDesc& graph, const Registry& registry);

}  // namespace kestrel::graphpaths
