#include <kestrel/Plugin.h>

#include "KeepExactPass.h"

KESTREL_PLUGIN(r) {
    r.add<KeepExactPass>();
}
