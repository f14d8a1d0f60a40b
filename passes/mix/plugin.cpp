#include <kestrel/Plugin.h>

#include "MixPass.h"

KESTREL_PLUGIN(r) {
    r.add<MixPass>();
}
