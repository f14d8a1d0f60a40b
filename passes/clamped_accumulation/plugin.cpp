#include <kestrel/Plugin.h>

#include "ClampedAccumulationPass.h"

KESTREL_PLUGIN(r) {
    r.add<kestrel::passes::ClampedAccumulationPass>();
}
