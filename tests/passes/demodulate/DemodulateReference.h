#pragma once
// Plain scalar reference of the Demodulate pass: the straightforward per-pixel form
// (ImageView::at() reads, branches on the optional inputs), kept to check the optimised pass
// against: illumination = sanitize((sanitize(color) - sanitize(emission)) / albedo'), albedo'
// = px::demodulationAlbedo(albedo, max(albedoFloor, 1e-8)); below the floor the light is not
// divided; without ids a pixel without light gets none and the albedo output is
// px::modulationAlbedo (with ids: demodulationAlbedo).
#include <kestrel/Image.h>
#include <kestrel/PixelMath.h>

#include <algorithm>

namespace demodref {

using namespace kestrel;

struct Outputs {
    Image illumination, albedo;  ///< albedo: what Modulate multiplies back by
};

/// albedo, emission: null when not bound; withIds: objectId bound (no guard of black pixels).
inline Outputs demodulate(const Image& color, const Image* albedo, const Image* emission,
                          float albedoFloor, bool withIds = false) {
    Outputs out{Image(color.extent(), Format::Float3), Image(color.extent(), Format::Float3)};
    const float floor = std::max(albedoFloor, 1e-8f);
    for (int y = 0; y < color.height(); ++y)
        for (int x = 0; x < color.width(); ++x)
            for (int c = 0; c < 3; ++c) {
                float v = px::sanitize(color.at(c, x, y));
                if (emission) v -= px::sanitize(emission->at(c, x, y));
                if (albedo) {
                    const float a = albedo->at(c, x, y);
                    const float m = withIds ? px::demodulationAlbedo(a, floor)
                                            : px::modulationAlbedo(a, v, floor);
                    if (a == px::demodulationAlbedo(a, floor))
                        v /= m;  // demodulated (m is the albedo)
                    else if (v < 0.f && !withIds)
                        v = 0.f;  // below the floor: undivided; no light of its own: none
                    out.albedo.at(c, x, y) = m;
                }
                out.illumination.at(c, x, y) = px::sanitize(v);
            }
    return out;
}

}  // namespace demodref
