#include "kestrel/Plugin.h"

#include <dlfcn.h>

#include <algorithm>
#include <cstdlib>

#include "kestrel/Log.h"

namespace kestrel {

namespace fs = std::filesystem;

PluginLoader::~PluginLoader() {
    for (auto it = handles_.rbegin(); it != handles_.rend(); ++it) dlclose(*it);
}

void PluginLoader::load(const fs::path& module, Registry& registry) {
    const std::string name = module.string();
    dlerror();
    void* handle = dlopen(name.c_str(), RTLD_NOW | RTLD_LOCAL);
    if (!handle) {
        const char* why = dlerror();
        throw Error("plugin " + name + ": cannot be loaded: " + (why ? why : "unknown error"));
    }
    using AbiFn = uint32_t (*)();
    using RegisterFn = void (*)(PluginRegistrar&);
    auto abi = reinterpret_cast<AbiFn>(dlsym(handle, "kestrelPluginAbiVersion"));
    auto reg = reinterpret_cast<RegisterFn>(dlsym(handle, "kestrelRegisterPlugin"));
    if (!abi || !reg) {
        dlclose(handle);
        throw Error("plugin " + name + ": missing entry point " +
                    (abi ? "kestrelRegisterPlugin" : "kestrelPluginAbiVersion") +
                    " (define it with KESTREL_PLUGIN)");
    }
    uint32_t version = abi();
    if (version != KESTREL_PLUGIN_ABI_VERSION) {
        dlclose(handle);
        throw Error("plugin " + name + ": built for plugin ABI version " + std::to_string(version) +
                    ", this kestrel uses version " + std::to_string(KESTREL_PLUGIN_ABI_VERSION) +
                    "; rebuild the plugin against this kestrel");
    }
    // Keep the module loaded even if registration fails part-way: types it did register
    // hold function pointers into it.
    handles_.push_back(handle);
    names_.push_back(name);
    PluginRegistrar registrar(registry, name);
    try {
        reg(registrar);
    } catch (const Error& e) {
        throw Error("plugin " + name + ": " + e.what());
    } catch (const std::exception& e) {
        throw Error("plugin " + name + ": registration failed: " + e.what());
    }
    spdlog::debug("loaded plugin {}", name);
}

void PluginLoader::loadDirectories(const std::vector<fs::path>& dirs, Registry& registry) {
    for (const auto& dir : dirs) {
        std::error_code ec;
        if (!fs::is_directory(dir, ec)) {
            spdlog::debug("plugin directory {} does not exist; skipped", dir.string());
            continue;
        }
        // Error-code forms throughout: an unreadable folder or a broken entry is reported as
        // an Error naming it, never as an escaping filesystem_error.
        std::vector<fs::path> modules;
        fs::directory_iterator it(dir, ec);
        for (; !ec && it != fs::directory_iterator(); it.increment(ec)) {
            std::error_code fec;
            if (it->is_regular_file(fec) && it->path().extension() == ".so")
                modules.push_back(it->path());
        }
        if (ec)
            throw Error("plugin directory " + dir.string() + ": cannot be read: " + ec.message());
        std::sort(modules.begin(), modules.end());
        for (const auto& m : modules) load(m, registry);
    }
}

namespace {
/// A folder the user named that holds nothing is most likely a typo: say so once, then run on
/// (the built-in passes may be all the graph needs).
void warnIfNotDirectory(const fs::path& dir) {
    std::error_code ec;
    if (fs::is_directory(dir, ec)) return;
    spdlog::warn("KESTREL_PLUGIN_PATH: {} {}; no plugins loaded from it", dir.string(),
                 fs::exists(dir, ec) ? "is not a directory" : "does not exist");
}
}  // namespace

HelperModule openHelperModule(const std::string& file) {
    HelperModule m;
    const auto dirs = defaultPluginDirectories();
    if (dirs.empty()) {
        m.error = file + ": no plugin folder to look beside";
        return m;
    }
    m.path = dirs.front().parent_path() / file;
    m.handle = ::dlopen(m.path.c_str(), RTLD_NOW | RTLD_LOCAL);
    if (!m.handle) {
        const char* e = ::dlerror();
        m.error = e ? e : m.path.string() + ": not found";
    }
    return m;
}

void* HelperModule::symbol(const char* name) const {
    return handle ? ::dlsym(handle, name) : nullptr;
}

std::vector<fs::path> defaultPluginDirectories() {
    std::vector<fs::path> dirs;
    // The plugin folder sits beside the framework library: <libdir>/kestrel/plugins, in the
    // build tree and in an install alike.
    Dl_info info{};
    if (dladdr(reinterpret_cast<void*>(&defaultPluginDirectories), &info) && info.dli_fname) {
        std::error_code ec;
        fs::path lib = fs::weakly_canonical(fs::path(info.dli_fname), ec);
        dirs.push_back(lib.parent_path() / KESTREL_PLUGIN_SUBDIR);
    }
    if (const char* env = std::getenv("KESTREL_PLUGIN_PATH")) {
        std::string s = env;
        size_t start = 0;
        while (start <= s.size()) {
            size_t end = s.find(':', start);
            if (end == std::string::npos) end = s.size();
            if (end > start) {
                dirs.emplace_back(s.substr(start, end - start));
                warnIfNotDirectory(dirs.back());
            }
            start = end + 1;
        }
    }
    return dirs;
}

}  // namespace kestrel
