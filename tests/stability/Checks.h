#pragma once
// Assertions shared by the stability tests: every frame finite and inside the plausible range.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <string>

#include "StabilityRig.h"

namespace stability {

/// Radiance range of plainScene's colour (0.05 + [0.3, 0.7] * [0.5, 2.0)).
constexpr float kPlainLo = 0.2f, kPlainHi = 1.55f;

/// Float rounding of long weighted sums: a relative slack on the range bound.
inline float slack(float lo, float hi) {
    return 1e-4f * std::max(std::fabs(lo), std::fabs(hi)) + 1e-6f;
}

struct Checked {
    ImageStats worst;         ///< min/max over all frames, non-finite count summed
    std::vector<float> last;  ///< last frame's output
};

/// Runs `g` and expects every frame's output finite and within [lo, hi] (+- slack).
inline Checked runBounded(const TestGraph& g, int frames, float lo, float hi, int threads = 1,
                          const std::string& what = "") {
    Checked r;
    r.worst.min = std::numeric_limits<float>::max();
    r.worst.max = -std::numeric_limits<float>::max();
    const float s = slack(lo, hi);
    RunOptions o;
    o.frames = frames;
    o.threads = threads;
    o.onFrame = [&](int64_t f, const kestrel::ImageView& out) {
        const ImageStats st = stats(out);
        EXPECT_EQ(st.nonFinite, 0u) << what << " frame " << f << ": non-finite output values";
        if (out.pixels() * size_t(out.channels()) > st.nonFinite) {  // some finite values
            EXPECT_GE(st.min, lo - s) << what << " frame " << f;
            EXPECT_LE(st.max, hi + s) << what << " frame " << f;
            r.worst.min = std::min(r.worst.min, st.min);
            r.worst.max = std::max(r.worst.max, st.max);
        }
        r.worst.nonFinite += st.nonFinite;
    };
    r.last = run(g, o);
    return r;
}

/// Bitwise equality of two planar outputs (NaN-safe: compares bit patterns).
inline bool bitwiseEqual(const std::vector<float>& a, const std::vector<float>& b) {
    return a.size() == b.size() && std::equal(a.begin(), a.end(), b.begin(), [](float x, float y) {
               return std::memcmp(&x, &y, sizeof(float)) == 0;
           });
}

}  // namespace stability
