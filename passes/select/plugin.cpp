#include <kestrel/Plugin.h>

#include "SelectPass.h"

KESTREL_PLUGIN(r) {
    r.add<SelectPass>();
}
