#pragma once
// The loader's policy for NaN, infinite and absurd input values (docs/errors.md): each is
// replaced by its output's fill value as the value is made (decoded, or summed), while it is
// in cache, and counted for the frame's one warning line.
#include <atomic>
#include <cmath>
#include <cstddef>

namespace kestrel::exr {

// No render's light, depth (1e10 on the sky), vector or id comes near this; issue 40 reported
// -1e38 albedo in one frame leaving values up to 3.8e8 in the history nine frames later.
constexpr float kAbsurd = 1e30f;

/// Replaces NaN, infinite and absurd (|v| > kAbsurd) values of [v, v + n) by `fill`; how many.
inline size_t replaceAbsurd(float* v, size_t n, float fill) {
    size_t count = 0;
    for (size_t i = 0; i < n; ++i)
        if (!(std::fabs(v[i]) <= kAbsurd)) v[i] = fill, ++count;
    return count;
}

/// One decoded channel's share of the policy: replace its absurd values by `fill` (when `on`)
/// and count them in `replaced` (decoding threads add to it).
struct AbsurdFix {
    bool on = false;
    float fill = 0.f;
    std::atomic<size_t>* replaced = nullptr;
};

}  // namespace kestrel::exr
