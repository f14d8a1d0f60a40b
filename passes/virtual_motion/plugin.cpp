#include <kestrel/Plugin.h>

#include "VirtualMotionPass.h"

KESTREL_PLUGIN(r) {
    r.add<VirtualMotionPass>();
}
