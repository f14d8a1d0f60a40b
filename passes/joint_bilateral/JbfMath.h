#pragma once
// Branch-free scalar math for the joint bilateral tap loop, written so that GCC/Clang
// auto-vectorise it (no libm calls, no errno): exp of a non-positive argument and acos^2.
#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>

namespace kestrel::passes::jbf {

/// e^a for a <= 0, 0 below -87 (where e^a is no longer a normal float). Cephes expf: Cody-Waite
/// range reduction a = n ln2 + r, degree-6 polynomial on |r| <= ln2/2; relative error < 2e-7.
inline float expNonPositive(float a) {
    const float ac = std::max(a, -87.f);
    // Round to nearest by the 1.5 * 2^23 trick (vectorises; exact for |t| < 2^22).
    const float t = ac * 1.44269504088896341f;
    const float n = (t + 12582912.f) - 12582912.f;
    float r = ac - n * 0.693359375f;
    r = r + n * 2.12194440e-4f;
    float p = 1.9875691500e-4f;
    p = p * r + 1.3981999507e-3f;
    p = p * r + 8.3334519073e-3f;
    p = p * r + 4.1665795894e-2f;
    p = p * r + 1.6666665459e-1f;
    p = p * r + 5.0000001201e-1f;
    const float y = p * r * r + r + 1.f;
    const float scale = std::bit_cast<float>((int32_t(n) + 127) << 23);  // 2^n, n in [-126, 0]
    const float v = y * scale;
    return a > -87.f ? v : 0.f;
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
