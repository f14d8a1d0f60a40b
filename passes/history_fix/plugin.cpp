#include <kestrel/Plugin.h>

#include "HistoryFixPass.h"

KESTREL_PLUGIN(r) {
    r.add<HistoryFixPass>();
}
