#pragma once
// Plugin modules. A plugin is a shared library exporting two C entry points:
//   uint32_t kestrelPluginAbiVersion();            must return KESTREL_PLUGIN_ABI_VERSION
//   void     kestrelRegisterPlugin(PluginRegistrar&);
// Write them with the KESTREL_PLUGIN macro:
//   KESTREL_PLUGIN(registrar) { registrar.add<MyPass>(); }
#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "kestrel/Registry.h"

// 4: PassIO reads ports by handle (kestrel/Declare.h).
#define KESTREL_PLUGIN_ABI_VERSION 4u

namespace kestrel {

/// Handed to a plugin's entry point; registers its types on behalf of that module.
class PluginRegistrar {
public:
    PluginRegistrar(Registry& registry, std::string module)
        : registry_(registry), module_(std::move(module)) {}
    template <class T>
    void add() {
        registry_.add<T>(module_);
    }
    void add(PassDesc desc, PassFactory factory) {
        registry_.add(std::move(desc), std::move(factory), module_);
    }

private:
    Registry& registry_;
    std::string module_;
};

/// Loads plugin modules and keeps them loaded for as long as it lives. Declare it before (so
/// it outlives) every pass instance created from its types.
class PluginLoader {
public:
    PluginLoader() = default;
    ~PluginLoader();
    PluginLoader(const PluginLoader&) = delete;
    PluginLoader& operator=(const PluginLoader&) = delete;

    /// Loads one module into `registry`. Throws Error naming the file for: not loadable,
    /// missing entry point, ABI mismatch, duplicate type name.
    void load(const std::filesystem::path& module, Registry& registry);
    /// Loads every module (*.so) in each directory, in sorted order. Missing dirs are skipped.
    void loadDirectories(const std::vector<std::filesystem::path>& dirs, Registry& registry);

    const std::vector<std::string>& loaded() const { return names_; }

private:
    std::vector<void*> handles_;
    std::vector<std::string> names_;
};

/// The install's plugin directory followed by those in KESTREL_PLUGIN_PATH (':'-separated).
std::vector<std::filesystem::path> defaultPluginDirectories();

/// A helper module: a shared library beside the plugin folder (<libdir>/kestrel/<file>) that a
/// plugin or tool opens only when it needs the library the module links (OpenImageIO,
/// OpenColorIO), so that kestrel does not load that library at every start.
struct HelperModule {
    std::filesystem::path path;
    void* handle = nullptr;  ///< null when it could not be opened (see error)
    std::string error;       ///< why not: dlerror's line, which names the file
    /// The entry point `name`, or null (also when the module is not open).
    void* symbol(const char* name) const;
};

/// Opens the helper module `file` (RTLD_NOW | RTLD_LOCAL); it is never closed, so what it returns
/// stays valid for the process. Open each once (std::call_once): a second call opens it again.
HelperModule openHelperModule(const std::string& file);

}  // namespace kestrel

#if defined(_WIN32)
#define KESTREL_EXPORT __declspec(dllexport)
#else
#define KESTREL_EXPORT __attribute__((visibility("default")))
#endif

#define KESTREL_PLUGIN(registrarName)                                                  \
    extern "C" KESTREL_EXPORT uint32_t kestrelPluginAbiVersion() {                     \
        return KESTREL_PLUGIN_ABI_VERSION;                                             \
    }                                                                                  \
    extern "C" KESTREL_EXPORT void kestrelRegisterPlugin(::kestrel::PluginRegistrar&); \
    extern "C" KESTREL_EXPORT void kestrelRegisterPlugin(::kestrel::PluginRegistrar& registrarName)
