#pragma once
// The reference against the mean of many 1-spp frames of a static scene: whether the reference
// is the expectation the frames estimate (shared by the room's and the zoo's tests).
#include <scenegen/SceneGen.h>

#include <algorithm>
#include <cmath>
#include <vector>

namespace scenegentest {

struct ExpectationCheck {
    double relBias = 0;  ///< |mean of the frames - reference| / reference, over the image
    double zRms = 0;     ///< RMS over pixels of the difference in units of its standard deviation
};

inline ExpectationCheck referenceAgainstFrameMean(const kestrel::scenegen::SceneOptions& o,
                                                  int frames) {
    const size_t n = size_t(o.width) * size_t(o.height);
    std::vector<double> sum(3 * n, 0.0), sum2(3 * n, 0.0);
    for (int t = 1; t <= frames; ++t) {
        const kestrel::scenegen::FrameAovs f = kestrel::scenegen::renderFrame(o, t);
        for (int c = 0; c < 3; ++c)
            for (size_t k = 0; k < n; ++k) {
                sum[c * n + k] += f.color[c][k];
                sum2[c * n + k] += double(f.color[c][k]) * f.color[c][k];
            }
    }
    const std::vector<float> ref = kestrel::scenegen::renderReference(o, 1);
    double meanNoisy = 0, meanRef = 0, z2 = 0;
    int zCount = 0;
    for (size_t k = 0; k < 3 * n; ++k) {
        const double mean = sum[k] / frames;
        const double var = std::max(0.0, sum2[k] / frames - mean * mean);
        meanNoisy += mean;
        meanRef += ref[k];
        // The difference of two independent estimates has variance var/frames + var/spp.
        const double sigma2 = var / frames + var / o.referenceSpp;
        if (sigma2 > 1e-12) {
            z2 += (mean - ref[k]) * (mean - ref[k]) / sigma2;
            ++zCount;
        }
    }
    return {std::fabs(meanNoisy - meanRef) / meanRef, std::sqrt(z2 / std::max(zCount, 1))};
}

}  // namespace scenegentest
