#pragma once
// Random and extreme Float3 images for the Demodulate / Modulate equivalence tests and
// benchmarks.
#include <kestrel/Image.h>

#include <limits>
#include <random>
#include <vector>

#include "../../ExtremeValues.h"

namespace modtest {

/// Values in [0, scale) (HDR-ish: squared uniform, a few large), a fraction `extremes` of them
/// replaced by NaN, +-Inf, huge, zero, negative and denormal values.
inline kestrel::Image randomImage(int w, int h, unsigned seed, float scale, float extremes) {
    kestrel::Image im(w, h, kestrel::Format::Float3);
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> u(0.f, 1.f);
    const std::vector<float> vals = testvalues::extremeValuesAnd({1e16f, 1e-3f, 9.99e-4f, 1e-8f});
    const int kVals = int(vals.size());
    for (int c = 0; c < 3; ++c)
        for (size_t i = 0; i < im.extent().pixels(); ++i) {
            float v = scale * u(rng) * u(rng) * (u(rng) < 0.02f ? 100.f : 1.f);
            if (u(rng) < extremes) v = vals[int(u(rng) * kVals) % kVals];
            im.channel(c)[i] = v;
        }
    return im;
}

}  // namespace modtest
