#pragma once
// Shared by the CLI's subcommands: logging set-up, plugin loading, preparing a graph with the
// user's --input/--output/--set, and printing diagnostics.
#include <graphpaths/GraphPaths.h>
#include <kestrel/Compiler.h>
#include <kestrel/Graph.h>
#include <kestrel/Plugin.h>
#include <kestrel/Registry.h>

#include <filesystem>
#include <functional>
#include <memory>
#include <string>
#include <vector>

namespace kestrel::cli {

/// Verbosity shared by all subcommands (-v).
extern bool gVerbose;
void setupLogging(bool verbose);

/// Registry with every plugin from the default directories loaded. The loader must outlive
/// every pass created from the registry.
struct Plugins {
    PluginLoader loader;
    Registry registry;
};
std::unique_ptr<Plugins> loadPlugins();

// Sources and writers as --input and --output see them (shared with the Python module).
using graphpaths::isSource;
using graphpaths::isSourceType;
using graphpaths::sourcePath;

/// The graph shipped under `name` (e.g. "svgf.json"): install share dir or source tree.
std::filesystem::path shippedGraph(const std::string& name);

/// Options every graph-running command takes.
struct GraphOptions {
    std::string graph;                 ///< path; empty: the default SVGF graph
    std::vector<std::string> inputs;   ///< PATTERN or name=PATTERN
    std::vector<std::string> outputs;  ///< PATTERN or name=PATTERN
    std::vector<std::string> sets;     ///< pass.param=value
    std::string outDir = "kestrel-out";
    bool keepPasses = false;  ///< --keep-passes: keepPasses=true on every writer that has it
};

/// Loads the graph, applies --input/--output/--set. A source left without a path runs on the
/// built-in scene (generated on first use); a sink without a path writes under outDir.
GraphDesc prepareGraph(const GraphOptions& options, const Registry& registry);

/// The "pass.port" that feeds the graph's first writer (sink), added to the graph's marked
/// outputs so it can be read in memory. With `detach`, the writers are removed (benchmarks time
/// the filter, not file writing). Throws Error when the graph has no writer.
std::string markSinkInput(GraphDesc& graph, const Registry& registry, bool detach);

/// Prints every diagnostic of a GraphError on stderr, one per line. With the graph, a JSON path
/// into a pass also names it as the user writes it in --set: "passes[1].params.alpha (taa.alpha)".
void printGraphError(const GraphError& e, const GraphDesc* graph = nullptr);

/// Throws GraphError, one line per override, when an override (`--set` or `--sweep`, `option`)
/// sets only passes the compiled graph leaves out for this scene: it would silently do nothing.
void refuseUnusedOverrides(const CompiledGraph& compiled, const std::vector<std::string>& sets,
                           const Registry& registry, const std::string& option = "--set");

/// Runs `fn`; a GraphError or Error it throws (bad options, a graph that does not prepare) is
/// printed, one line per finding, and gives exit code 2 (docs/errors.md).
int exitTwoOnUsageError(const std::function<int()>& fn);

/// Throws Error (a usage error, before frame 1) naming the frames of `asked` before the input's
/// first frame or after its last, and the frames it has; nothing when `available` is empty (a
/// source that cannot list them). A gap inside the sequence is left to the run (exit 1).
void checkFramesExist(const std::vector<int64_t>& asked, std::vector<int64_t> available,
                      const std::string& option, const std::string& input,
                      const std::string& remedy = "give a range inside it");

/// Parses "1-100", "1-100x2", "3,4,10-20x2" into frame numbers (Error naming the text).
std::vector<int64_t> parseFrameList(const std::string& text);

}  // namespace kestrel::cli
