#include <kestrel/Plugin.h>

#include "ModulatePass.h"

KESTREL_PLUGIN(r) {
    r.add<ModulatePass>();
}
