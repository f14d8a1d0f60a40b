#include <kestrel/Plugin.h>

#include "ATrousPass.h"

KESTREL_PLUGIN(r) {
    r.add<ATrousPass>();
}
