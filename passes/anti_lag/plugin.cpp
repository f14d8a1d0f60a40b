#include <kestrel/Plugin.h>

#include "AntiLagPass.h"

KESTREL_PLUGIN(r) {
    r.add<AntiLagPass>();
}
