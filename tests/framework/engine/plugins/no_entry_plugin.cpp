// A loadable shared library that is not a kestrel plugin: it exports no entry point.
#include <kestrel/Plugin.h>

extern "C" KESTREL_EXPORT int notAKestrelPlugin() {
    return 7;
}
