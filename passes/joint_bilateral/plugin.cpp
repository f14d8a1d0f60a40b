#include <kestrel/Plugin.h>

#include "JointBilateralPass.h"

KESTREL_PLUGIN(r) {
    r.add<kestrel::passes::JointBilateralPass>();
}
