#include <kestrel/Plugin.h>

#include "ToneMapPass.h"

KESTREL_PLUGIN(r) {
    r.add<kestrel::passes::ToneMapPass>();
}
