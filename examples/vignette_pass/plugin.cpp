// The plugin's entry points: kestrel loads this module and calls it to register its pass types.
#include <kestrel/Plugin.h>

#include "VignettePass.h"

KESTREL_PLUGIN(r) {
    r.add<vignette::VignettePass>();
}
