#pragma once
// Branch-free scalar math for the joint bilateral tap loop, written so that GCC/Clang
// auto-vectorise it (no libm calls, no errno): 2^t of a non-positive argument and acos^2.
#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>

namespace kestrel::passes::jbf {

/// 2^t for t <= 0, exactly 0 below -126 (where 2^t is no longer a normal float). Cephes exp2f:
/// t = n + f with n integer and |f| <= 1/2, 2^f = 1 + f P(f) with a degree-5 P; relative error
/// < 2e-7. Base 2 because the callers fold log2(e) into their constants: one multiply less.
inline float exp2NonPositive(float t) {
    const float tc = std::max(t, -126.f);
    // Round to nearest by the 1.5 * 2^23 trick (vectorises; exact for |tc| < 2^22).
    const float n = (tc + 12582912.f) - 12582912.f;
    const float f = tc - n;
    float p = 1.535336188319500e-4f;
    p = p * f + 1.339887440266574e-3f;
    p = p * f + 9.618437357674640e-3f;
    p = p * f + 5.550332471162809e-2f;
    p = p * f + 2.402264791363012e-1f;
    p = p * f + 6.931472028550421e-1f;
    const float y = p * f + 1.f;
    const float scale = std::bit_cast<float>((int32_t(n) + 127) << 23);  // 2^n, n in [-126, 0]
    const float v = y * scale;
    return t > -126.f ? v : 0.f;
}

/// Abramowitz & Stegun 4.4.46: acos(x) = sqrt(1 - x) * poly(x) + e, |e| <= 2e-8 on [0, 1].
inline float acosPoly(float x) {
    float p = -0.0012624911f;
    p = p * x + 0.0066700901f;
    p = p * x - 0.0170881256f;
    p = p * x + 0.0308918810f;
    p = p * x - 0.0501743046f;
    p = p * x + 0.0889789874f;
    p = p * x - 0.2145988016f;
    p = p * x + 1.5707963050f;
    return p;
}

/// acos(x)^2 for x clamped to [0, 1], without a square root: (1 - x) * poly(x)^2. For x < 0 it
/// returns (pi/2)^2, a lower bound of the true value: callers use it only where any angle of
/// pi/2 or more already gives weight 0 (see JointBilateralPass.cpp).
inline float acosSquaredAcute(float x) {
    x = std::min(std::max(x, 0.f), 1.f);  // (NaN cannot occur: inputs are sanitised)
    const float p = acosPoly(x);
    return (1.f - x) * p * p;
}

/// acos(x)^2 for x clamped to [-1, 1] (acos(-x) = pi - acos(x)).
inline float acosSquared(float x) {
    x = std::min(std::max(x, -1.f), 1.f);
    const float ax = std::fabs(x);
    const float a = std::sqrt(1.f - ax) * acosPoly(ax);
    const float obtuse = 3.14159265358979f - a;
    const float t = x < 0.f ? obtuse : a;
    return t * t;
}

}  // namespace kestrel::passes::jbf
