// The vector tap kernel: the bilinear (and Catmull-Rom) taps of a row's pixels whose footprint lies
// inside the image, bit-identical to reprojectPixel (PixelReprojection-inl.h).
// Included once per SIMD target by Reproject.cpp (hwy/foreach_target.h): the toggled guard.
#if defined(KESTREL_REPROJECTION_TAP_KERNEL_INL_H_) == defined(HWY_TARGET_TOGGLE)
#ifdef KESTREL_REPROJECTION_TAP_KERNEL_INL_H_
#undef KESTREL_REPROJECTION_TAP_KERNEL_INL_H_
#else
#define KESTREL_REPROJECTION_TAP_KERNEL_INL_H_
#endif

#include <hwy/highway.h>
#include <kestrel/Kestrel.h>
#include <kestrel/SimdMath.h>

#include <algorithm>
#include <cstdint>
#include <type_traits>

#include "PixelReprojection-inl.h"

HWY_BEFORE_NAMESPACE();
namespace kestrel::HWY_NAMESPACE {
namespace {

namespace hn = hwy::HWY_NAMESPACE;

// The tap kernel: one vector of pixels of a row at a time, everything in registers. Where every
// lane's taps lie inside the image at one integer offset (x0 = x + dx, y0 = y + dy, the common
// case: motion varies slowly) the taps are contiguous loads; elsewhere they are gathered per
// lane. Lanes whose taps may leave the image, invalid positions and the 3x3 fallback (weight sum
// below 1e-4) are recomputed afterwards by reprojectPixel. Every operation is the reference's,
// in its order and with its roundings (this file is built without contraction: a fused
// multiply-add is std::fma there and MulAdd here), with masked selects where the scalar code
// skips a tap, so results are bit-identical to reprojectPixel
// (tests/passes/reprojection, 0 ulp) and independent of how rows are split among threads.
//
// On the targets without an FMA instruction (SSE4, the baseline) MulAdd rounds the product
// first, so the kernel would differ from reprojectPixel by rounding, and a rounding can flip a
// consistency test at its threshold (a whole tap in or out). There every pixel takes
// reprojectPixel instead (slower, and still bit-identical): kTapKernel.
constexpr bool kTapKernel = HWY_NATIVE_FMA;
using simd::DF;
using simd::DI;
using simd::MF;
using simd::VF;
using simd::VI;

/// One row's per-pixel terms (scratch rows) and output rows.
struct RowTerms {
    const float *zRef, *n0, *n1, *n2, *invZ, *invN;
    const float *bw[4], *wx[4], *wy[4];  ///< bilinear and (Catmull-Rom) separable weights
    const int32_t* refId;
    float* sumW;
    float *oc[3], *om[2], *oh;
    bool hasC, hasM, hasH;
    int32_t* taps;          ///< output row of the taps mask (TapMode::Record)
    const int32_t* shared;  ///< input row of sharedTaps (TapMode::Shared)
};

/// How the tap kernel decides consistency: test, test and record the outcomes (output `taps`),
/// or take them from sharedTaps.
enum class TapMode { Test, Record, Shared };

/// How a vector's taps are loaded: Contig, every lane with the same integer offset (plain
/// loads); Window, the lanes' offsets within one row, or two adjacent rows, and 14 columns of
/// each other (AVX-512 only: two loads and a two-table permute per row instead of a gather,
/// the same values); Gather, anything else.
enum class Load { Contig, Window, Gather };

/// Window: the lanes' taps in the 32 elements from `base` (tap (-1, -1) of the leftmost lane
/// offset) on, lane l's tap (k, j) at perm[l] + k + 1 of row j (+ 1 where `lower`).
struct WindowTerms {
    VI perm;
    MF lower;  ///< lanes whose row offset is the larger of two (twoRows)
    bool twoRows;
};

#if HWY_TARGET <= HWY_AVX3
constexpr bool kWindowLoads = true;
inline VF permute2(VF a, VI idx, VF b) {
    return VF{_mm512_permutex2var_ps(a.raw, idx.raw, b.raw)};
}
inline VI permute2(VI a, VI idx, VI b) {
    return VI{_mm512_permutex2var_epi32(a.raw, idx.raw, b.raw)};
}
#else
constexpr bool kWindowLoads = false;
template <class V>
V permute2(V a, VI, V) {
    return a;  // never called: kWindowLoads
}
#endif

// Geo: the depth and normal tests run (geometryTests); without them only the object id is
// tested, which is what the tests with infinite thresholds give bit for bit (every distance
// they compare is finite).
// One function of ~170 lines, on purpose: it is the kernel, and its tests, masks, weight sums
// and resampling share the vectors loaded once, kept in registers (split up, they would pass
// through memory), in the reference's order step by step.
template <Load L, bool CR, bool Geo, TapMode M>
HWY_INLINE void tapVector(const Sources& S, const RowTerms& R, int x, ptrdiff_t base, VI idx,
                          const WindowTerms& win) {
    const DF d;
    const DI di;
    const ptrdiff_t w = S.w;
    auto window = [&](auto dtag, const auto* p, int k, int j) HWY_ATTR {
        const auto* row = p + base + ptrdiff_t(j + 1) * w;
        const VI ix = hn::Add(win.perm, hn::Set(di, k + 1));
        auto v = permute2(hn::LoadU(dtag, row), ix, hn::LoadU(dtag, row + hn::Lanes(dtag)));
        if (win.twoRows) {
            row += w;
            const auto v2 =
                permute2(hn::LoadU(dtag, row), ix, hn::LoadU(dtag, row + hn::Lanes(dtag)));
            v = hn::IfThenElse(hn::RebindMask(dtag, win.lower), v2, v);
        }
        return v;
    };
    auto ld = [&](const float* p, int k, int j) HWY_ATTR {
        if constexpr (L == Load::Contig)
            return hn::LoadU(d, p + base + ptrdiff_t(j) * w + k);
        else if constexpr (L == Load::Window)
            return window(d, p, k, j);
        else
            return hn::GatherIndex(d, p, hn::Add(idx, hn::Set(di, int32_t(j * w + k))));
    };
    auto ldId = [&](int k, int j) HWY_ATTR {
        if constexpr (L == Load::Contig)
            return hn::LoadU(di, S.pIds + base + ptrdiff_t(j) * w + k);
        else if constexpr (L == Load::Window)
            return window(di, S.pIds, k, j);
        else
            return hn::GatherIndex(di, S.pIds, hn::Add(idx, hn::Set(di, int32_t(j * w + k))));
    };
    const VF zR = hn::LoadU(d, R.zRef + x), c0 = hn::LoadU(d, R.n0 + x),
             c1 = hn::LoadU(d, R.n1 + x), c2 = hn::LoadU(d, R.n2 + x);
    const VF iz = hn::LoadU(d, R.invZ + x), in = hn::LoadU(d, R.invN + x);
    const VF in2 = hn::Mul(in, in);
    const VI rid = hn::LoadU(di, R.refId + x);
    const VF dThr = hn::Set(d, S.dThr), nThr2 = hn::Set(d, S.nThr2), zero = hn::Zero(d);
    const VI shared = M == TapMode::Shared ? hn::LoadU(di, R.shared + x) : hn::Zero(di);
    VI record = hn::Zero(di);  // TapMode::Record: the outcomes
    auto recordTap = [&](MF passed, int k, int j) HWY_ATTR {
        if constexpr (M == TapMode::Record)
            record = hn::Or(record, hn::IfThenElseZero(hn::RebindMask(di, passed),
                                                       hn::Set(di, int32_t(1) << tapBit(k, j))));
    };
    // The consistency test of the tap at (x0 + k, y0 + j) (SVGF; Falcor's isReprjValid), the
    // normal distance compared squared: no square root per tap.
    auto consistent = [&](int k, int j) HWY_ATTR {
        if constexpr (M == TapMode::Shared)
            return hn::RebindMask(d, hn::TestBit(shared, hn::Set(di, int32_t(1) << tapBit(k, j))));
        MF ok = hn::FirstN(d, hn::Lanes(d));
        if constexpr (Geo) {
            const VF dz = hn::Mul(hn::Abs(hn::Sub(zR, simd::sanitizeDepth(ld(S.pz, k, j)))), iz);
            const VF d0 = hn::Sub(c0, simd::sanitizeNormal(ld(S.pn[0], k, j)));
            const VF d1 = hn::Sub(c1, simd::sanitizeNormal(ld(S.pn[1], k, j)));
            const VF d2 = hn::Sub(c2, simd::sanitizeNormal(ld(S.pn[2], k, j)));
            const VF dn2 = hn::MulAdd(d2, d2, hn::MulAdd(d1, d1, hn::Mul(d0, d0)));
            ok = hn::AndNot(hn::Gt(dz, dThr), hn::Le(hn::Mul(dn2, in2), nThr2));
        }
        if (S.pIds) ok = hn::And(ok, hn::RebindMask(d, hn::Eq(ldId(k, j), rid)));
        return ok;
    };
    const MF k00 = consistent(0, 0), k10 = consistent(1, 0), k01 = consistent(0, 1),
             k11 = consistent(1, 1);
    recordTap(k00, 0, 0);
    recordTap(k10, 1, 0);
    recordTap(k01, 0, 1);
    recordTap(k11, 1, 1);
    // Catmull-Rom (TAA histories): 4x4 where all 16 taps are consistent. The outer 12 are tested
    // only where the inner four passed, in reprojectPixel's order, and recorded as passed while
    // every earlier one passed (reprojectPixel stops at the first failure), so the taps are the
    // same bits on every path and target; tested whether or not the colour is consumed, since a
    // sharedTaps consumer may resample it.
    MF all16 = hn::FirstN(d, 0);
    if constexpr (CR) {
        if (R.hasC || M == TapMode::Record) {
            all16 = hn::And(hn::And(k00, k10), hn::And(k01, k11));
            for (int j = -1; j <= 2 && !hn::AllFalse(d, all16); ++j)
                for (int k = -1; k <= 2; ++k)
                    if (j < 0 || j > 1 || k < 0 || k > 1) {
                        all16 = hn::And(all16, consistent(k, j));
                        recordTap(all16, k, j);
                    }
        }
    }
    const VF w0 = hn::LoadU(d, R.bw[0] + x), w1 = hn::LoadU(d, R.bw[1] + x),
             w2 = hn::LoadU(d, R.bw[2] + x), w3 = hn::LoadU(d, R.bw[3] + x);
    // Taps that count: consistent with positive weight, summed in tap order.
    const MF a0 = hn::And(k00, hn::Gt(w0, zero)), a1 = hn::And(k10, hn::Gt(w1, zero)),
             a2 = hn::And(k01, hn::Gt(w2, zero)), a3 = hn::And(k11, hn::Gt(w3, zero));
    VF sw = zero;
    sw = hn::IfThenElse(a0, hn::Add(sw, w0), sw);
    sw = hn::IfThenElse(a1, hn::Add(sw, w1), sw);
    sw = hn::IfThenElse(a2, hn::Add(sw, w2), sw);
    sw = hn::IfThenElse(a3, hn::Add(sw, w3), sw);
    hn::StoreU(sw, d, R.sumW + x);
    const VF inv = hn::Div(hn::Set(d, 1.f), sw);  // sw < 1e-4 (or 0): recomputed by reprojectPixel
    // acc = fma(wt, v, acc) as in reprojectPixel, except the history length's, whose product is
    // rounded before the sum (MulAdd(wt, v, 0) is that rounded product).
    auto bilinear = [&](const float* p, auto sanitizeTap, auto roundedProduct) HWY_ATTR {
        auto add = [&](VF acc, VF wt, VF v) HWY_ATTR {
            if constexpr (decltype(roundedProduct)::value)
                return hn::Add(acc, hn::MulAdd(wt, v, zero));
            return hn::MulAdd(wt, v, acc);
        };
        VF acc = zero;
        acc = hn::IfThenElse(a0, add(acc, w0, sanitizeTap(ld(p, 0, 0))), acc);
        acc = hn::IfThenElse(a1, add(acc, w1, sanitizeTap(ld(p, 1, 0))), acc);
        acc = hn::IfThenElse(a2, add(acc, w2, sanitizeTap(ld(p, 0, 1))), acc);
        acc = hn::IfThenElse(a3, add(acc, w3, sanitizeTap(ld(p, 1, 1))), acc);
        return hn::Mul(acc, inv);
    };
    using FusedSum = std::false_type;  // acc + wt * v in one rounding
    using RoundedProduct = std::true_type;
    auto radiance = [](VF v) HWY_ATTR { return simd::sanitize(v); };
    // Planes that are not fed contribute wt * 0: the output is 0 wherever the kernel's result
    // is kept.
    if (R.hasC) {
        VF col[3];
        // Catmull-Rom clamped to the inner 2x2 taps' range so negative lobes cannot ring; the
        // bilinear colour only where some lane is not Catmull-Rom.
        const bool allCR = CR && hn::AllTrue(d, all16);
        if (!allCR)
            for (int c = 0; c < 3; ++c)
                col[c] = S.pc[c] ? bilinear(S.pc[c], radiance, FusedSum{}) : zero;
        if constexpr (CR) {
            if (!hn::AllFalse(d, all16)) {
                VF wx[4], wy[4];
                for (int k = 0; k < 4; ++k) {
                    wx[k] = hn::LoadU(d, R.wx[k] + x);
                    wy[k] = hn::LoadU(d, R.wy[k] + x);
                }
                for (int c = 0; c < 3; ++c) {
                    VF s = zero, lo = hn::Set(d, 3e38f), hi = hn::Set(d, -3e38f);
                    for (int j = 0; j < 4; ++j)
                        for (int k = 0; k < 4; ++k) {
                            const VF v = simd::sanitize(ld(S.pc[c], k - 1, j - 1));
                            s = hn::MulAdd(hn::Mul(wx[k], wy[j]), v, s);
                            if (j >= 1 && j <= 2 && k >= 1 && k <= 2) {
                                lo = hn::IfThenElse(hn::Lt(v, lo), v, lo);  // std::min(lo, v)
                                hi = hn::IfThenElse(hn::Lt(hi, v), v, hi);  // std::max(hi, v)
                            }
                        }
                    // px::clamp(s, lo, hi) = std::min(std::max(s, lo), hi)
                    const VF mx = hn::IfThenElse(hn::Lt(s, lo), lo, s);
                    const VF cr = hn::IfThenElse(hn::Lt(hi, mx), hi, mx);
                    col[c] = allCR ? cr : hn::IfThenElse(all16, cr, col[c]);
                }
            }
        }
        for (int c = 0; c < 3; ++c) hn::StoreU(col[c], d, R.oc[c] + x);
    }
    if (R.hasM) {
        const VF m0 = S.pm[0] ? bilinear(S.pm[0], radiance, FusedSum{}) : zero;
        const VF m1 =
            S.pm[1] ? bilinear(
                          S.pm[1], [](VF v) HWY_ATTR { return simd::sanitizePositive(v, 1e32f); },
                          FusedSum{})
                    : zero;
        hn::StoreU(m0, d, R.om[0] + x);
        hn::StoreU(m1, d, R.om[1] + x);
    }
    if (R.hasH) {
        // Without prevHistoryLength every tap adds wt * 1 = wt: the sum is sw's, term by term.
        const VF hl = S.ph
                          ? bilinear(
                                S.ph, [](VF v) HWY_ATTR { return simd::sanitizePositive(v, 1e6f); },
                                RoundedProduct{})
                          : hn::Mul(sw, inv);
        hn::StoreU(hl, d, R.oh + x);
    }
    if constexpr (M == TapMode::Record) hn::StoreU(record, di, R.taps + x);
}

/// The kernel over pixels [a, b) of one row (b - a >= one vector): vectors at x = a, a + n, ...,
/// the last one moved left to end at b (its overlap is computed twice, to the same values), so
/// no lane is stored past the range.
template <bool CR, bool Geo, TapMode M>
void tapRow(const Sources& S, const RowTerms& R, int y, int a, int b, const int32_t* rFast,
            const int32_t* rDx, const int32_t* rDy) {
    const DF d;
    const DI di;
    const int w = S.w, n = int(hn::Lanes(d));
    const VI zeroI = hn::Zero(di);
    // Lanes that do not take the kernel gather from a safe element (every tap offset of the
    // footprint, -1..2 rows and columns, stays inside the image: w, h >= 4 when any lane is
    // fast with Catmull-Rom, >= 2 with bilinear).
    const VI safe = hn::Set(di, CR ? int32_t(w + 1) : 0);
    const WindowTerms noWindow{zeroI, hn::FirstN(d, 0), false};
    const ptrdiff_t planeSize = ptrdiff_t(w) * S.h;
    for (int xs = a;; xs += n) {
        const int x = std::min(xs, b - n);
        const MF fast = hn::RebindMask(d, hn::Ne(hn::LoadU(di, rFast + x), zeroI));
        if (!hn::AllFalse(d, fast)) {
            const VI dx = hn::LoadU(di, rDx + x), dy = hn::LoadU(di, rDy + x);
            const int dx0 = rDx[x], dy0 = rDy[x];
            const bool allFast = hn::AllTrue(d, fast);
            if (allFast && hn::AllTrue(di, hn::And(hn::Eq(dx, hn::Set(di, dx0)),
                                                   hn::Eq(dy, hn::Set(di, dy0))))) {
                const ptrdiff_t base = ptrdiff_t(y + dy0) * w + ptrdiff_t(x + dx0);
                tapVector<Load::Contig, CR, Geo, M>(S, R, x, base, zeroI, noWindow);
                if (x == b - n) break;
                continue;
            }
            if constexpr (kWindowLoads) {
                // A camera's motion varies smoothly: a vector's offsets mostly span a column or
                // two of one row or two adjacent rows. The window spans rows dyMin - 1 .. dyMax
                // + 2 and 32 columns from dxMin - 1, all inside the plane.
                const int dxMin = hn::GetLane(hn::MinOfLanes(di, dx));
                const int dxMax = hn::GetLane(hn::MaxOfLanes(di, dx));
                const int dyMin = hn::GetLane(hn::MinOfLanes(di, dy));
                const int dyMax = hn::GetLane(hn::MaxOfLanes(di, dy));
                const ptrdiff_t base = ptrdiff_t(y + dyMin - 1) * w + ptrdiff_t(x + dxMin - 1);
                if (allFast && dxMax - dxMin <= n - 3 && dyMax - dyMin <= 1 && base >= 0 &&
                    base + ptrdiff_t(dyMax - dyMin + 3) * w + 2 * n <= planeSize) {
                    const WindowTerms win{hn::Add(hn::Iota(di, 0), hn::Sub(dx, hn::Set(di, dxMin))),
                                          hn::RebindMask(d, hn::Ne(dy, hn::Set(di, dyMin))),
                                          dyMax != dyMin};
                    tapVector<Load::Window, CR, Geo, M>(S, R, x, base, zeroI, win);
                    if (x == b - n) break;
                    continue;
                }
            }
            const VI idx = hn::Add(hn::Mul(hn::Add(dy, hn::Set(di, y)), hn::Set(di, w)),
                                   hn::Add(hn::Iota(di, x), dx));
            tapVector<Load::Gather, CR, Geo, M>(
                S, R, x, 0, hn::IfThenElse(hn::RebindMask(di, fast), idx, safe), noWindow);
        }
        if (x == b - n) break;
    }
}

/// tapRow for the filter (Catmull-Rom or bilinear) and whether the geometry is tested.
template <TapMode M>
void tapRows(const Sources& S, const RowTerms& R, int y, int a, int b, const int32_t* rFast,
             const int32_t* rDx, const int32_t* rDy, bool cr, bool geometry) {
    if (cr)
        geometry ? tapRow<true, true, M>(S, R, y, a, b, rFast, rDx, rDy)
                 : tapRow<true, false, M>(S, R, y, a, b, rFast, rDx, rDy);
    else
        geometry ? tapRow<false, true, M>(S, R, y, a, b, rFast, rDx, rDy)
                 : tapRow<false, false, M>(S, R, y, a, b, rFast, rDx, rDy);
}

}  // namespace
}  // namespace kestrel::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#endif  // toggled include guard
