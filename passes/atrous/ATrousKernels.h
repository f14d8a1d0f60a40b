#pragma once
// What ATrousPass.cpp (declaration, resolve, fusion) hands the fast path (ATrousKernels.cpp).
#include <cstdint>
#include <span>

#include "ATrousPass.h"

namespace kestrel {

/// One pass's bound images, shared by the fast and the exact path; null where an optional input
/// is not bound or an output not consumed.
struct ATrousBindings {
    explicit ATrousBindings(PassIO& io);
    ATrousBindings(PassIO& io, const ATrousPass::Declaration& d);
    const ImageView &color, &depth, &normal;
    const ImageView *var, *idView;
    const int32_t* ids;
    const ImageView& outColor;
    const ImageView* outVar;  ///< null without a variance input
};

/// The fast path (everything but `exact`) on the running CPU's best SIMD target: one signal, or
/// a fused pair (`signals` = 2) sharing the first's geometry and geometric settings; each
/// signal's own settings give its luminance weight (sigmaL, sigmaColor). Band scratch comes from
/// `idle` (PassIO::idlePlanes) where it suffices.
void atrousFilterFast(FrameContext& ctx, const ATrousBindings* const* b, int signals,
                      const ATrousPass::Settings* settings, std::span<float* const> idle);

}  // namespace kestrel
