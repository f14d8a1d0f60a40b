#pragma once
// Plain scalar reference of the Demodulate pass: the straightforward per-pixel form
// (ImageView::at() reads, branches on the optional inputs), kept to check the optimised pass
// against: illumination = sanitize((sanitize(color) - sanitize(emission)) / albedo'), albedo'
// = px::demodulationAlbedo(albedo, max(albedoFloor, 1e-8)).
#include <kestrel/Image.h>
#include <kestrel/PixelMath.h>

#include <algorithm>

namespace demodref {

using namespace kestrel;

/// albedo, emission: null when not bound.
inline Image demodulate(const Image& color, const Image* albedo, const Image* emission,
                        float albedoFloor) {
    Image out(color.extent(), Format::Float3);
    const float floor = std::max(albedoFloor, 1e-8f);
    for (int y = 0; y < color.height(); ++y)
        for (int x = 0; x < color.width(); ++x)
            for (int c = 0; c < 3; ++c) {
                float v = px::sanitize(color.at(c, x, y));
                if (emission) v -= px::sanitize(emission->at(c, x, y));
                if (albedo) v /= px::demodulationAlbedo(albedo->at(c, x, y), floor);
                out.at(c, x, y) = px::sanitize(v);
            }
    return out;
}

}  // namespace demodref
