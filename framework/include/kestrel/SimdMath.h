// Per-target header (Highway's "-inl.h" convention, no #pragma once): vector forms of
// PixelMath's helpers, for kernels written with Google Highway and compiled once per instruction
// set by hwy/foreach_target.h (run-time dispatch: SSE4, AVX2, AVX-512, and the baseline; see
// docs/benchmarks.md). A pass .cpp includes it after foreach_target.h, so each target's copy
// lands in that target's namespace (kestrel::N_AVX2::simd, ...) and inlines into the kernels
// of the same target, which call it as simd::...
//
// Each function evaluates the same formula as its scalar namesake in PixelMath.h. The vector
// forms spell out their fused multiply-adds (fused on AVX2 and AVX-512; SSE4 and the baseline
// have no FMA instruction, where Highway's MulAdd rounds the product first); in the scalar ones
// GCC decides (it contracts a * b + c by default in C++, even with -std=c++20, unlike ISO C), so
// results may differ from the scalar ones by a few ulp, never more. A kernel that must match a
// scalar reference bit for bit builds both without contraction (-ffp-contract=off) and writes
// MulAdd where the scalar code writes std::fma (Reprojection does, on the FMA targets).
//
// A pass that includes it links hwy::hwy (the framework itself does not).

// Toggled include guard: included once per target by foreach_target.h.
#if defined(KESTREL_SIMD_MATH_INL_H_) == defined(HWY_TARGET_TOGGLE)
#ifdef KESTREL_SIMD_MATH_INL_H_
#undef KESTREL_SIMD_MATH_INL_H_
#else
#define KESTREL_SIMD_MATH_INL_H_
#endif

#include <hwy/highway.h>

#include "kestrel/PixelMath.h"

HWY_BEFORE_NAMESPACE();
namespace kestrel::HWY_NAMESPACE::simd {

namespace hn = hwy::HWY_NAMESPACE;
using DF = hn::ScalableTag<float>;
using DI = hn::RebindToSigned<DF>;
using VF = hn::Vec<DF>;
using VI = hn::Vec<DI>;
using MF = hn::Mask<DF>;

/// Whether hn::MaskedLoad never touches masked-off lanes, so it may be given addresses past an
/// allocation's ends. Only AVX-512 suppresses those faults in hardware: Highway's scalar target
/// also reports HWY_MEM_OPS_MIGHT_FAULT 0, but its MaskedLoad reads the lane anyway (a heap
/// overflow ASan found in the A-Trous pass on a build without -march=native).
constexpr bool kMaskedLoadsCannotFault =
    HWY_ARCH_X86 && HWY_TARGET <= HWY_AVX3 && !HWY_MEM_OPS_MIGHT_FAULT;

/// Lanes per vector of this target.
inline size_t lanes() {
    return hn::Lanes(DF());
}

/// px::sanitize: NaN and +-Inf -> 0, finite values clamped to +-limit.
inline VF sanitize(VF v, float limit = px::kMaxRadiance) {
    const DF d;
    const VF c = hn::Min(hn::Max(v, hn::Set(d, -limit)), hn::Set(d, limit));
    return hn::IfThenElseZero(hn::Le(hn::Abs(v), hn::Set(d, px::kFloatMax)), c);
}

/// px::sanitizePositive: non-negative and finite, else 0; clamped to limit.
inline VF sanitizePositive(VF v, float limit = px::kMaxRadiance) {
    const DF d;
    const MF ok = hn::And(hn::Ge(v, hn::Zero(d)), hn::Le(v, hn::Set(d, px::kFloatMax)));
    return hn::IfThenElseZero(ok, hn::Min(v, hn::Set(d, limit)));
}

/// px::sanitizeDepth: NaN, Inf, negative or beyond background -> background depth.
inline VF sanitizeDepth(VF z) {
    const DF d;
    const VF bg = hn::Set(d, kBackgroundDepth);
    return hn::IfThenElse(hn::And(hn::Ge(z, hn::Zero(d)), hn::Lt(z, bg)), z, bg);
}

/// px::sanitizeNormal: a component outside [-2, 2] (or NaN) -> 0.
inline VF sanitizeNormal(VF v) {
    const DF d;
    return hn::IfThenElseZero(hn::Le(hn::Abs(v), hn::Set(d, 2.f)), v);
}

/// px::luminance (Rec. 709).
inline VF luminance(VF r, VF g, VF b) {
    const DF d;
    return hn::MulAdd(hn::Set(d, 0.0722f), b,
                      hn::MulAdd(hn::Set(d, 0.7152f), g, hn::Mul(hn::Set(d, 0.2126f), r)));
}

/// 2^f for f in [-0.5, 0.5]: px::fastExp2's polynomial (Cephes exp2f).
inline VF exp2Polynomial(VF f) {
    const DF d;
    VF p = hn::Set(d, 1.535336188319500e-4f);
    p = hn::MulAdd(p, f, hn::Set(d, 1.339887440266574e-3f));
    p = hn::MulAdd(p, f, hn::Set(d, 9.618437357674640e-3f));
    p = hn::MulAdd(p, f, hn::Set(d, 5.550332471162809e-2f));
    p = hn::MulAdd(p, f, hn::Set(d, 2.402264791363012e-1f));
    p = hn::MulAdd(p, f, hn::Set(d, 6.931472028550421e-1f));
    p = hn::MulAdd(p, f, hn::Set(d, 1.f));
    return p;
}

/// px::fastExp2: relative error below 3e-7 on [-126, 126]; exactly 0 below -126.5.
inline VF fastExp2(VF x) {
    const DF d;
#if HWY_TARGET <= HWY_AVX3
    // AVX-512: the same n and f (hardware round to nearest, ties to even, as the magic-number
    // addition below) and the same polynomial; vscalefps then applies 2^n and a zero mask
    // gives 0 below -126.5, in 10 instructions instead of 14. Equal to the generic form by
    // construction (the same n, f and polynomial; 2^n applied exactly, one rounding).
    const VF xc = hn::Min(x, hn::Set(d, 126.f));
    const VF n = hn::Round(xc);
    const VF f = hn::Sub(xc, n);
    const VF p = exp2Polynomial(f);
    const auto keep = hn::Ge(xc, hn::Set(d, -126.5f));
    return VF{_mm512_maskz_scalef_ps(keep.raw, p.raw, n.raw)};
#else
    const DI di;
    const VF xc = hn::Min(hn::Max(x, hn::Set(d, -127.f)), hn::Set(d, 126.f));
    const VF big = hn::Add(xc, hn::Set(d, px::kRoundMagic));
    const VF f = hn::Sub(xc, hn::Sub(big, hn::Set(d, px::kRoundMagic)));
    const VF p = exp2Polynomial(f);
    // (n + 127) << 23 from the rounded value's bits: no float-to-int conversion.
    const VI biased = hn::Sub(hn::BitCast(di, big), hn::Set(di, px::kRoundMagicBits - 127));
    return hn::Mul(p, hn::BitCast(d, hn::ShiftLeft<23>(biased)));
#endif
}

/// px::fastLog2 for x > 0 (callers clamp): absolute error below 1e-6 on normal floats.
inline VF fastLog2(VF x) {
    const DF d;
    const DI di;
    const VI bits = hn::BitCast(di, x);
    const VF e = hn::ConvertTo(d, hn::Sub(hn::ShiftRight<23>(bits), hn::Set(di, 127)));
    const VF m =
        hn::BitCast(d, hn::Or(hn::And(bits, hn::Set(di, 0x007fffff)), hn::Set(di, 0x3f800000)));
    const VF one = hn::Set(d, 1.f);
    const VF t = hn::Div(hn::Sub(m, one), hn::Add(m, one));
    const VF t2 = hn::Mul(t, t);
    VF s = hn::Set(d, 1.f / 9.f);
    s = hn::MulAdd(s, t2, hn::Set(d, 1.f / 7.f));
    s = hn::MulAdd(s, t2, hn::Set(d, 1.f / 5.f));
    s = hn::MulAdd(s, t2, hn::Set(d, 1.f / 3.f));
    s = hn::MulAdd(s, t2, one);
    return hn::MulAdd(hn::Set(d, 2.8853900817779268f), hn::Mul(t, s), e);
}

/// n when `p` is a whole number in [1, 4096] (then x^p is best taken by repeated squaring),
/// else 0.
inline int integerExponent(float p) {
    return p >= 1.f && p <= 4096.f && float(int(p)) == p ? int(p) : 0;
}

/// x^n for n >= 1 by binary exponentiation: relative error at most about 2 log2(n) ulp, exact
/// 0 for x = 0. Cheaper than exp2(n log2 x) for the normal weight's n = 128 (7 products).
inline VF powInt(VF x, int n) {
    if ((n & (n - 1)) == 0) {  // a power of two: squarings only, no data-dependent branches
        while (n > 1) {
            x = hn::Mul(x, x);
            n >>= 1;
        }
        return x;
    }
    VF result = hn::Set(DF(), 1.f);
    for (;;) {
        if (n & 1) result = hn::Mul(result, x);
        n >>= 1;
        if (!n) return result;
        x = hn::Mul(x, x);
    }
}

/// px::minAbsDiff with the neighbours' presence uniform across lanes.
inline VF minAbsDiff(VF prev, VF cur, VF next, bool hasPrev, bool hasNext) {
    const VF b = hn::Sub(cur, prev), f = hn::Sub(next, cur);
    if (!hasPrev) return hasNext ? f : hn::Zero(DF());
    if (!hasNext) return b;
    return hn::IfThenElse(hn::Le(hn::Abs(b), hn::Abs(f)), b, f);
}

}  // namespace kestrel::HWY_NAMESPACE::simd
HWY_AFTER_NAMESPACE();

#endif  // KESTREL_SIMD_MATH_INL_H_
