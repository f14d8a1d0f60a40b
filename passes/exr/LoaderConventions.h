#pragma once
// The loader's convention fixes (kestrel/Conventions.h): what a file stores turned into what
// the graph's passes expect.
#include <cstddef>

#include "ChannelPlan.h"

namespace kestrel::exr {

/// Object ids arrive as floats; stored in place as int32 (the plane's own memory).
void floatsToIds(float* plane, size_t n, IdRule rule);

}  // namespace kestrel::exr
