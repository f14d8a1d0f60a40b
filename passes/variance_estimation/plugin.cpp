#include <kestrel/Plugin.h>

#include "VarianceEstimationPass.h"

KESTREL_PLUGIN(r) {
    r.add<VarianceEstimationPass>();
}
