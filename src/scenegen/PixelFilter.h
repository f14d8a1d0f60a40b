#pragma once
// Importance sampling of a Blackman-Harris pixel filter (Blender's default shape), separably in
// x and y like Cycles: a sample offset drawn with the filter's density has weight 1, so the mean
// of jittered samples is the filtered image.
#include <algorithm>
#include <cmath>
#include <vector>

namespace kestrel::scenegen {

class PixelFilter {
public:
    /// `width` in pixels (the footprint is [-width/2, width/2]); <= 0: no filter (box of 0).
    explicit PixelFilter(float width) : width_(std::max(width, 0.f)) {
        if (width_ > 0.f) buildCdf();
    }
    bool active() const { return width_ > 0.f; }
    /// Offset from the pixel centre, in pixels, for a uniform u in [0, 1).
    float sample(float u) const {
        if (!active()) return 0.f;
        // Inverse of the tabulated CDF, linear inside a bin.
        const auto it = std::upper_bound(cdf_.begin(), cdf_.end(), u);
        const size_t bin = size_t(std::clamp<std::ptrdiff_t>(it - cdf_.begin() - 1, 0, kBins - 1));
        const float lo = cdf_[bin], hi = cdf_[bin + 1];
        const float f = hi > lo ? (u - lo) / (hi - lo) : 0.5f;
        return ((float(bin) + f) / float(kBins) - 0.5f) * width_;
    }

private:
    static constexpr int kBins = 256;

    static double blackmanHarris(double t) {  // t in [0, 1] across the footprint
        constexpr double kTwoPi = 6.283185307179586;
        return 0.35875 - 0.48829 * std::cos(kTwoPi * t) + 0.14128 * std::cos(2 * kTwoPi * t) -
               0.01168 * std::cos(3 * kTwoPi * t);
    }

    void buildCdf() {
        cdf_.assign(kBins + 1, 0.f);
        std::vector<double> acc(kBins + 1, 0.0);
        for (int b = 0; b < kBins; ++b)  // midpoint rule per bin
            acc[size_t(b + 1)] = acc[size_t(b)] + blackmanHarris((b + 0.5) / kBins);
        const double total = acc[kBins] > 0.0 ? acc[kBins] : 1.0;
        for (int b = 0; b <= kBins; ++b) cdf_[size_t(b)] = float(acc[size_t(b)] / total);
        cdf_[kBins] = 1.f;
    }

    float width_;
    std::vector<float> cdf_;
};

}  // namespace kestrel::scenegen
