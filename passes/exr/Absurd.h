#pragma once
// The loader's policy for NaN, infinite and absurd input values (docs/errors.md): each is
// replaced by its output's fill value as the value is made (decoded, or summed), while it is
// in cache, and counted for the frame's one warning line.
#include <atomic>
#include <cmath>
#include <cstddef>

namespace kestrel::exr {

// No render's light, depth (1e10 on the sky), vector or id comes near this; an input once had
// -1e38 albedo in one frame leaving values up to 3.8e8 in the history nine frames later.
constexpr float kAbsurd = 1e30f;

// Negative light is a pixel filter's negative lobe (Cycles' filters have none): at most ~13%
// (Lanczos) of the brightest light beside it, which in a Cycles render is the sun's disc (about
// 1.5e7 at 1000 W/m^2). Below this a value is damage: -1e10 in the colour of one frame left
// -1e7 in the history nine frames later.
constexpr float kMostNegativeLight = -1e8f;

/// Replaces NaN, infinite and absurd values (outside [lowest, kAbsurd]) of [v, v + n) by
/// `fill`; how many.
inline size_t replaceAbsurd(float* v, size_t n, float fill, float lowest = -kAbsurd) {
    size_t count = 0;
    for (size_t i = 0; i < n; ++i)
        if (!(v[i] >= lowest && v[i] <= kAbsurd)) v[i] = fill, ++count;
    return count;
}

/// One decoded channel's share of the policy: replace its values outside [lowest, kAbsurd] by
/// `fill` (when `on`) and count them in `replaced` (decoding threads add to it).
struct AbsurdFix {
    bool on = false;
    float fill = 0.f;
    std::atomic<size_t>* replaced = nullptr;
    float lowest = -kAbsurd;
};

}  // namespace kestrel::exr
