#include <kestrel/Plugin.h>

#include "ReprojectionPass.h"

KESTREL_PLUGIN(r) {
    r.add<ReprojectionPass>();
}
