// Screen-space derivatives of this frame's depth and normal: the tolerances of the consistency
// tests (SVGF, Schied et al. 2017, section 4.1).
// Included once per SIMD target by Reproject.cpp (hwy/foreach_target.h): the toggled guard.
#if defined(KESTREL_REPROJECTION_DERIVATIVES_INL_H_) == defined(HWY_TARGET_TOGGLE)
#ifdef KESTREL_REPROJECTION_DERIVATIVES_INL_H_
#undef KESTREL_REPROJECTION_DERIVATIVES_INL_H_
#else
#define KESTREL_REPROJECTION_DERIVATIVES_INL_H_
#endif

#include <hwy/highway.h>
#include <kestrel/Kestrel.h>
#include <kestrel/PixelMath.h>

#include <algorithm>
#include <cmath>

HWY_BEFORE_NAMESPACE();
namespace kestrel::HWY_NAMESPACE {
namespace {

// The rows a row of screen-space derivatives reads: sanitised depth and normal (sanitizeDepth,
// sanitizeNormal), each at rows y (index 0), y-1 (1) and y+1 (2); absent neighbour rows alias
// row y and are unused.
struct GeomRows {
    const float* z[3];
    const float* n[3][3];
    float depthStep;  ///< relative step r of the stored depth (kDepthPrecisionFact; 0: float)
};

// Screen-space derivatives (one-sided, edge-preserving: px::minAbsDiff) of pixel x, as
// 1 / (fwidth + 0.01) of depth and normal, plus the sanitised normal. L, R, U, D: whether the
// left, right, upper and lower neighbours exist (compile-time, so the interior is branch-free).
template <bool L, bool R, bool U, bool D>
__attribute__((always_inline)) inline void derivativesAt(const GeomRows& g, int x, float* invZ,
                                                         float* invN, float* n0, float* n1,
                                                         float* n2) {
    const int xl = L ? x - 1 : x, xr = R ? x + 1 : x;  // an absent side is never used
    const float zc = g.z[0][x];
    // A background pixel has no slope: it matches only the background. With the slope to its
    // surface neighbours (1e10 between two of them, a jittered render's isolated sky pixel) it
    // would pass every tap and take a surface's history into the sky.
    const bool surface = zc < kBackgroundDepth;
    const float fwZ = std::fabs(px::minAbsDiff(g.z[0][xl], zc, g.z[0][xr], L, R)) +
                      std::fabs(px::minAbsDiff(g.z[1][x], zc, g.z[2][x], U, D));
    float dnx2 = 0, dny2 = 0;
    float nc[3];
    for (int c = 0; c < 3; ++c) {
        const float* const* p = g.n[c];
        nc[c] = p[0][x];
        const float gx = px::minAbsDiff(p[0][xl], nc[c], p[0][xr], L, R);
        const float gy = px::minAbsDiff(p[1][x], nc[c], p[2][x], U, D);
        dnx2 += gx * gx;
        dny2 += gy * gy;
    }
    n0[x] = nc[0];
    n1[x] = nc[1];
    n2[x] = nc[2];
    const float fwN = surface ? std::sqrt(dnx2) + std::sqrt(dny2) : 0.f;
    // Depth stored with relative step r (half: 2^-10) differs from last frame's by up to two
    // steps where nothing moved: the tolerance grows by 2 r z (r = 0 adds exactly nothing).
    invZ[x] = 1.f / ((surface ? fwZ : 0.f) + 2.f * g.depthStep * zc + 1e-2f);
    invN[x] = 1.f / (fwN + 1e-2f);
}

// Derivatives of pixels [a, b) of one row: the row's two end pixels separately, the interior in
// a loop with fixed neighbours (contiguous loads, no selects), which the compiler vectorises.
template <bool U, bool D>
HWY_INLINE void rowDerivativesT(const GeomRows& rows, int w, int a, int b, float* __restrict invZ,
                                float* __restrict invN, float* __restrict n0, float* __restrict n1,
                                float* __restrict n2) {
    const GeomRows g = rows;  // a local copy: the row pointers stay in registers
    if (w == 1) {
        derivativesAt<false, false, U, D>(g, 0, invZ, invN, n0, n1, n2);
        return;
    }
    if (a == 0) derivativesAt<false, true, U, D>(g, 0, invZ, invN, n0, n1, n2);
    const int i0 = std::max(a, 1), i1 = std::min(b, w - 1);
#pragma GCC ivdep
    for (int x = i0; x < i1; ++x) derivativesAt<true, true, U, D>(g, x, invZ, invN, n0, n1, n2);
    if (b == w) derivativesAt<true, false, U, D>(g, w - 1, invZ, invN, n0, n1, n2);
}

HWY_INLINE void rowDerivatives(const GeomRows& g, bool u, bool d, int w, int a, int b, float* invZ,
                               float* invN, float* n0, float* n1, float* n2) {
    if (u && d)
        rowDerivativesT<true, true>(g, w, a, b, invZ, invN, n0, n1, n2);
    else if (u)
        rowDerivativesT<true, false>(g, w, a, b, invZ, invN, n0, n1, n2);
    else if (d)
        rowDerivativesT<false, true>(g, w, a, b, invZ, invN, n0, n1, n2);
    else
        rowDerivativesT<false, false>(g, w, a, b, invZ, invN, n0, n1, n2);
}

}  // namespace
}  // namespace kestrel::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#endif  // toggled include guard
