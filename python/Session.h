#pragma once
// The pass registry every graph of the process uses: the plugins of the default directories
// (those `kestrel` loads), loaded once at first use and kept loaded while any graph, compiled
// graph or run holds the session (passes come from the plugins' code).
#include <kestrel/Plugin.h>
#include <kestrel/Registry.h>

#include <memory>

namespace kestrel::python {

struct Session {
    PluginLoader loader;  // declared first: outlives the registry's factories
    Registry registry;
};

std::shared_ptr<Session> session();

}  // namespace kestrel::python
