#pragma once
// The reprojection of one frame on the running CPU's best SIMD target (Reproject.cpp).
#include "ReprojectionPass.h"

namespace kestrel {

void reprojectFrame(FrameContext& ctx, PassIO& io, const ReprojectionPass::Settings& settings);

}  // namespace kestrel
