#include <kestrel/Plugin.h>

#include "AlbedoResolvePass.h"

KESTREL_PLUGIN(r) {
    r.add<AlbedoResolvePass>();
}
