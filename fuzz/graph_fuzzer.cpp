// libFuzzer entry: graph JSON -> parseGraph -> compileGraph(validateOnly) against the real
// plugins (loaded once from the build tree's plugin directory).
#include <kestrel/Plugin.h>
#include <kestrel/Registry.h>
#include <spdlog/spdlog.h>

#include <cstdio>
#include <cstdlib>
#include <memory>

#include "FuzzTargets.h"

namespace {
struct Plugins {
    kestrel::PluginLoader loader;
    kestrel::Registry registry;
};
Plugins* plugins = nullptr;
}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
    spdlog::set_level(spdlog::level::off);  // per-input log lines would dominate the run time
    plugins = new Plugins;  // lives for the whole process (passes hold code from the modules)
    plugins->loader.loadDirectories({KESTREL_PLUGIN_BUILD_DIR}, plugins->registry);
    if (plugins->registry.all().empty()) {
        std::fprintf(stderr, "graph_fuzzer: no plugins in %s\n", KESTREL_PLUGIN_BUILD_DIR);
        std::abort();
    }
    return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    kestrel::fuzz::graphTarget(data, size, plugins->registry);
    return 0;
}
