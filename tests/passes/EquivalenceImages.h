#pragma once
// Inputs for the equivalence tests of optimised kernels against their plain scalar references:
// random G-buffers with object and depth edges, and the same sprinkled with extreme values
// (tests/ExtremeValues.h: NaN, +-Inf, 1e30, negatives, denormals, signed zeros).
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "../ExtremeValues.h"
#include "SvgfTestImages.h"

namespace svgftest {

struct RandomGBuffer {
    Image color, depth, normal, ids;
};

/// Piecewise surfaces (a new object every ~23 columns, a depth step every ~17 rows) with noisy
/// radiance, slightly perturbed unit normals and smoothly varying depth.
inline RandomGBuffer randomGBuffer(int w, int h, int seed) {
    RandomGBuffer g{Image(w, h, Format::Float3), Image(w, h, Format::Float),
                    Image(w, h, Format::Float3), Image(w, h, Format::Int32)};
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            const int obj = x / 23 + 7 * (y / 17);
            for (int c = 0; c < 3; ++c)
                g.color.at(c, x, y) = 4.f * hash01(x, y, seed + c) * hash01(x, y, seed + 9 + c);
            g.depth.at(0, x, y) = 2.f + float(obj % 5) + 0.01f * float(x) + 0.003f * float(y);
            float n[3] = {0.2f * (hash01(x, y, seed + 20) - 0.5f) + 0.1f * float(obj % 3),
                          0.2f * (hash01(x, y, seed + 21) - 0.5f), 1.f};
            const float len = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
            for (int c = 0; c < 3; ++c) g.normal.at(c, x, y) = n[c] / len;
            g.ids.atInt(x, y) = obj % 4;
        }
    return g;
}

/// Overwrites about `fraction` of the values of every channel with extreme ones.
inline void sprinkleExtremes(Image& im, int seed, float fraction = 0.03f) {
    const std::vector<float>& kExtremes = testvalues::extremeValues();
    const int n = int(kExtremes.size());
    for (int c = 0; c < std::max(1, kestrel::channelCount(im.format())); ++c)
        for (int y = 0; y < im.height(); ++y)
            for (int x = 0; x < im.width(); ++x)
                if (hash01(x, y, seed + 100 * c) < fraction)
                    im.at(c, x, y) =
                        kExtremes[int(hash01(x, y, seed + 100 * c + 1) * float(n)) % n];
}

/// Largest |a - b| / (|b| + scale) over all values; where = "channel c at (x, y)" of the worst.
/// Both NaN counts as equal, one NaN as infinitely different.
inline double maxScaledDiff(const Image& a, const Image& b, float scale, std::string* where) {
    double worst = 0;
    for (int c = 0; c < kestrel::channelCount(b.format()); ++c)
        for (int y = 0; y < b.height(); ++y)
            for (int x = 0; x < b.width(); ++x) {
                const float va = a.at(c, x, y), vb = b.at(c, x, y);
                double d;
                if (std::isnan(va) || std::isnan(vb))
                    d = std::isnan(va) && std::isnan(vb) ? 0 : INFINITY;
                else if (va == vb)
                    d = 0;
                else
                    d = std::fabs(double(va) - double(vb)) / (std::fabs(double(vb)) + scale);
                if (d > worst) {
                    worst = d;
                    if (where)
                        *where = "channel " + std::to_string(c) + " at (" + std::to_string(x) +
                                 ", " + std::to_string(y) + "): " + std::to_string(va) + " vs " +
                                 std::to_string(vb);
                }
            }
    return worst;
}

}  // namespace svgftest
