#include <kestrel/Plugin.h>

#include "TaaPass.h"

KESTREL_PLUGIN(r) {
    r.add<kestrel::passes::TaaPass>();
}
