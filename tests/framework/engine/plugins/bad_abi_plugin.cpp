// A plugin built for another plugin ABI: the entry points are written by hand so the version
// can lie. The loader must refuse it before calling kestrelRegisterPlugin.
#include <kestrel/Plugin.h>

#include <cstdlib>

extern "C" KESTREL_EXPORT uint32_t kestrelPluginAbiVersion() {
    return 999u;
}

extern "C" KESTREL_EXPORT void kestrelRegisterPlugin(kestrel::PluginRegistrar&) {
    std::abort();  // never reached: registering would run code built for another ABI
}
