#pragma once
// For tests that compile shipped graphs in-process: the project's pass plugins as this build made
// them (KESTREL_PLUGIN_BUILD_DIR), loaded once per test binary, and the writer swapped for a
// marked output.
#include <kestrel/Graph.h>
#include <kestrel/Plugin.h>
#include <kestrel/Registry.h>

#include <string>

namespace testutil {

inline const kestrel::Registry& builtPlugins() {
    static const struct Loaded {
        kestrel::PluginLoader loader;
        kestrel::Registry registry;
        Loaded() { loader.loadDirectories({KESTREL_PLUGIN_BUILD_DIR}, registry); }
    } loaded;
    return loaded.registry;
}

/// Replaces the shipped graph's writer ("output") by a marked output of what feeds its colour,
/// so results stay float32 in memory; returns the marked "pass.port". (Its other inputs, the
/// input's alpha, go with it.)
inline std::string markWriterInput(kestrel::GraphDesc& g) {
    std::string marked;
    for (const auto& e : g.edges)
        if (e.toPass == "output" && e.toPort == "color") marked = e.fromPass + "." + e.fromPort;
    std::erase_if(g.edges, [](const kestrel::EdgeDesc& e) { return e.toPass == "output"; });
    std::erase_if(g.passes, [](const kestrel::PassNode& p) { return p.name == "output"; });
    g.outputs.push_back(marked);
    return marked;
}

}  // namespace testutil
