#pragma once
// Plain scalar reference of the Modulate pass: the straightforward per-pixel form
// (ImageView::at() reads, branches on the optional inputs), kept to check the optimised pass
// against: color = sanitize(sanitize(illumination) * albedo' + sanitize(emission) +
// sanitize(base)), albedo' = px::demodulationAlbedo(albedo, max(albedoFloor, 1e-8)), every
// product and sum rounded on its own (the test is compiled with -ffp-contract=off).
#include <kestrel/Image.h>
#include <kestrel/PixelMath.h>

#include <algorithm>

namespace modref {

using namespace kestrel;

/// albedo, emission, base: null when not bound.
inline Image modulate(const Image& illum, const Image* albedo, const Image* emission,
                      const Image* base, float albedoFloor) {
    Image out(illum.extent(), Format::Float3);
    const float floor = std::max(albedoFloor, 1e-8f);
    for (int y = 0; y < illum.height(); ++y)
        for (int x = 0; x < illum.width(); ++x)
            for (int c = 0; c < 3; ++c) {
                float v = px::sanitize(illum.at(c, x, y));
                if (albedo) v *= px::demodulationAlbedo(albedo->at(c, x, y), floor);
                if (emission) v += px::sanitize(emission->at(c, x, y));
                if (base) v += px::sanitize(base->at(c, x, y));
                out.at(c, x, y) = px::sanitize(v);
            }
    return out;
}

}  // namespace modref
