#pragma once
// Header-only per-pixel helpers shared by the filter passes: luminance, sanitising, guarded
// division, and branch-free exp2/log2 approximations that GCC and Clang auto-vectorise (libm's
// expf/powf do not vectorise without -ffast-math, and the A-Trous inner loop evaluates one
// exponential per tap).
#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>

#include "kestrel/Conventions.h"

namespace kestrel::px {

/// Largest radiance magnitude a filter keeps. Chosen so that luminance^2 (second moments),
/// weighted sums of 49 taps and the 4x variance boost stay far from float overflow (3.4e38).
constexpr float kMaxRadiance = 1e16f;
constexpr float kFloatMax = std::numeric_limits<float>::max();

/// Rec. 709 luminance (docs/design.md section 7).
inline float luminance(float r, float g, float b) {
    return 0.2126f * r + 0.7152f * g + 0.0722f * b;
}

/// Radiance sanitiser: NaN and +-Inf become 0 (an invalid sample carries no information),
/// finite values are clamped to +-kMaxRadiance. Branch-free (vectorises).
inline float sanitize(float v, float limit = kMaxRadiance) {
    // Every comparison with NaN is false, so NaN takes the last branch.
    float c = std::min(std::max(v, -limit), limit);
    return std::fabs(v) <= kFloatMax ? c : 0.f;
}

/// Non-negative, finite (variances, history lengths, weights).
inline float sanitizePositive(float v, float limit = kMaxRadiance) {
    return v >= 0.f && v <= kFloatMax ? std::min(v, limit) : 0.f;
}

/// The albedo that Demodulate divides by and Modulate multiplies by (the same value, so the two
/// are inverse). Below the floor the channel is not demodulated at all (divisor 1): dividing a
/// lit pixel by a near-black albedo amplifies it up to 1/floor, and the spatial filters then
/// spread that into neighbours with ordinary albedo (found by the stability suite). NaN/Inf -> 1.
inline float demodulationAlbedo(float albedo, float floor) {
    return albedo >= floor && albedo <= 1e30f ? albedo : 1.f;
}

/// The albedo Modulate multiplies back by, given the channel's light (colour - emission) at the
/// pixel: the albedo demodulationAlbedo divides by, except that below the floor it is 1 only
/// where the pixel has light of its own (not demodulated: it goes through the filters as it
/// is), and the floor where it has none. A black pixel then gets back what the filters spread
/// into it from lit neighbours scaled by the floor instead of whole (an emitter's pixels: its
/// diffuse albedo is 0; objects without ids are not kept apart). NaN/Inf albedo: as below.
inline float modulationAlbedo(float albedo, float light, float floor) {
    return albedo >= floor && albedo <= 1e30f ? albedo : (light > 0.f ? 1.f : floor);
}

/// Linear depth: NaN, Inf, negative or beyond background become the background depth.
inline float sanitizeDepth(float z) {
    return z >= 0.f && z < kBackgroundDepth ? z : kBackgroundDepth;
}

/// Normal component: non-finite becomes 0 (a zero normal matches nothing in the weights).
inline float sanitizeNormal(float v) {
    return std::fabs(v) <= 2.f ? v : 0.f;
}

inline float clamp(float v, float lo, float hi) {
    return std::min(std::max(v, lo), hi);
}

/// a / b, or `fallback` when |b| is below `tiny` (or the result is not finite).
inline float safeDiv(float a, float b, float fallback = 0.f, float tiny = 1e-20f) {
    if (!(std::fabs(b) > tiny)) return fallback;
    float r = a / b;
    return std::fabs(r) <= kFloatMax ? r : fallback;
}

/// Adding this (1.5 * 2^23) to a float of magnitude below 2^22 rounds it to an integer n held
/// in the low mantissa bits: bits(x + kRoundMagic) = kRoundMagicBits + n.
constexpr float kRoundMagic = 12582912.f;
constexpr int32_t kRoundMagicBits = 0x4B400000;

/// 2^x, relative error below 3e-7 for x in [-126, 126] (measured, tests/passes/atrous);
/// exactly 0 below -126.5, 2^126 above 126. Range reduction x = n + f with n = round(x) and
/// |f| <= 1/2, then 2^f by the degree-6 polynomial of Cephes' exp2f (Moshier). Clamping to
/// -127 makes the exponent field 0 (the float +0), so no select is needed. Round-to-nearest by
/// the kRoundMagic addition: no float-to-int conversion (slow in SIMD), no std::floor.
inline float fastExp2(float x) {
    const float xc = std::min(std::max(x, -127.f), 126.f);
    const float big = xc + kRoundMagic;
    const float n = big - kRoundMagic;
    const float f = xc - n;
    float p = 1.535336188319500e-4f;
    p = p * f + 1.339887440266574e-3f;
    p = p * f + 9.618437357674640e-3f;
    p = p * f + 5.550332471162809e-2f;
    p = p * f + 2.402264791363012e-1f;
    p = p * f + 6.931472028550421e-1f;
    p = p * f + 1.f;
    const int32_t i = std::bit_cast<int32_t>(big) - kRoundMagicBits;  // = n
    return p * std::bit_cast<float>((i + 127) << 23);
}

/// log2(x) for normal positive finite x (callers clamp to >= 1e-30), absolute error < 2e-6.
/// x = 2^e * m, m in [1,2); log2(m) = 2/ln2 * atanh((m-1)/(m+1)) by its odd series.
inline float fastLog2(float x) {
    int32_t bits = std::bit_cast<int32_t>(x);
    float e = float((bits >> 23) - 127);
    float m = std::bit_cast<float>((bits & 0x007fffff) | 0x3f800000);
    float t = (m - 1.f) / (m + 1.f);
    float t2 = t * t;
    float s = 1.f / 9.f;
    s = s * t2 + 1.f / 7.f;
    s = s * t2 + 1.f / 5.f;
    s = s * t2 + 1.f / 3.f;
    s = s * t2 + 1.f;
    return e + 2.8853900817779268f * t * s;  // 2 / ln 2
}

/// Of the backward and forward differences, the one with the smaller magnitude: a screen-space
/// derivative that does not jump across a depth or normal edge (a central difference there would
/// widen the edge-stopping tolerance exactly where it must be tight). 0 at 1-pixel extents.
inline float minAbsDiff(float prev, float cur, float next, bool hasPrev, bool hasNext) {
    float b = cur - prev, f = next - cur;
    if (!hasPrev) return hasNext ? f : 0.f;
    if (!hasNext) return b;
    return std::fabs(b) <= std::fabs(f) ? b : f;
}

constexpr float kLog2e = 1.4426950408889634f;

/// e^x via fastExp2.
inline float fastExp(float x) {
    return fastExp2(x * kLog2e);
}

}  // namespace kestrel::px
