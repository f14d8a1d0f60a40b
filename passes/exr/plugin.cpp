#include <kestrel/Plugin.h>

#include "ExrLoader.h"
#include "ExrWriter.h"

KESTREL_PLUGIN(r) {
    r.add<kestrel::exr::ExrLoader>();
    r.add<kestrel::exr::ExrWriter>();
}
