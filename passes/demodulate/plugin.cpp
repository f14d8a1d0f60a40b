#include <kestrel/Plugin.h>

#include "DemodulatePass.h"

KESTREL_PLUGIN(r) {
    r.add<DemodulatePass>();
}
