#include <kestrel/Plugin.h>

#include "TemporalAccumulationPass.h"

KESTREL_PLUGIN(r) {
    r.add<TemporalAccumulationPass>();
}
