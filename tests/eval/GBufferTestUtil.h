#pragma once
// G-buffers for the region tests: one grey surface filling the frame.
#include <eval/Regions.h>

namespace testutil {

/// A flat grey (albedo 0.5, not glossy, not emissive) surface of object 1 facing the camera at
/// `depth`, every pixel moving by (mx, my) px per frame.
inline kestrel::eval::GBuffer greySurface(int width, int height, float depth, float mx = 0.f,
                                          float my = 0.f) {
    kestrel::eval::GBuffer g;
    g.width = width;
    g.height = height;
    const size_t n = size_t(width) * size_t(height);
    g.depth.assign(n, depth);
    g.objectId.assign(n, 1);
    g.emissionLum.assign(n, 0.f);
    g.albedoLum.assign(n, 0.5f);
    g.specularLum.assign(n, 0.f);
    g.motionX.assign(n, mx);
    g.motionY.assign(n, my);
    return g;
}

}  // namespace testutil
