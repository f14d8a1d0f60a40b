#include <kestrel/Plugin.h>

#include "BackgroundEmissionPass.h"

KESTREL_PLUGIN(r) {
    r.add<BackgroundEmissionPass>();
}
