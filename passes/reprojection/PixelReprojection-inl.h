// The per-pixel reprojection (bilinear taps, 3x3 fallback, Catmull-Rom), scalar: the reference
// the tap kernel (TapKernel-inl.h) matches bit for bit, and what it leaves to it.
// Included once per SIMD target by Reproject.cpp (hwy/foreach_target.h): the toggled guard.
#if defined(KESTREL_REPROJECTION_PIXEL_REPROJECTION_INL_H_) == defined(HWY_TARGET_TOGGLE)
#ifdef KESTREL_REPROJECTION_PIXEL_REPROJECTION_INL_H_
#undef KESTREL_REPROJECTION_PIXEL_REPROJECTION_INL_H_
#else
#define KESTREL_REPROJECTION_PIXEL_REPROJECTION_INL_H_
#endif

#include <hwy/highway.h>
#include <kestrel/Kestrel.h>
#include <kestrel/PixelMath.h>

#include <algorithm>
#include <cmath>
#include <cstdint>

HWY_BEFORE_NAMESPACE();
namespace kestrel::HWY_NAMESPACE {
namespace {

// Catmull-Rom weights of the 4 taps around a fraction t in [0,1).
inline void catmullRomWeights(float t, float w[4]) {
    const float t2 = t * t, t3 = t2 * t;
    w[0] = -0.5f * t3 + t2 - 0.5f * t;
    w[1] = 1.5f * t3 - 2.5f * t2 + 1.f;
    w[2] = -1.5f * t3 + 2.f * t2 + 0.5f * t;
    w[3] = 0.5f * t3 - 0.5f * t2;
}

// The taps mask (output `taps`, input `sharedTaps`): which taps passed the consistency tests,
// so that a second reprojection over the same geometry and motion (the specular chain's) reuses
// them instead of testing again. Bits 0-15: the 4x4 Catmull-Rom footprint, tap (x0 + k, y0 + j)
// for k, j in -1..2 at bit (j + 1) 4 + k + 1 (the bilinear 2x2 are bits 5, 6, 9 and 10); bits
// 16-24: the 3x3 fallback, tap (cx + k, cy + j) for k, j in -1..1 at 16 + (j + 1) 3 + k + 1.
// Taps never tested are 0: a bilinear reprojection tests no outer tap, so a Catmull-Rom one
// given its taps resamples bilinearly.
constexpr int tapBit(int k, int j) {
    return (j + 1) * 4 + k + 1;
}
constexpr int fallbackBit(int k, int j) {
    return 16 + (j + 1) * 3 + k + 1;
}

// Every plane the taps read, and the parameters of the consistency test.
struct Sources {
    int w = 0, h = 0;
    const float *pz = nullptr, *pn[3] = {};
    const int32_t* pIds = nullptr;  ///< null without ids (every id test passes)
    const float *pc[3] = {}, *pm[2] = {}, *ph = nullptr;  ///< null when not fed
    float dThr = 0;
    float nThr2 = 0;  ///< the normal threshold squared (the test compares squared distances)
    bool catmullRom = false;          ///< Catmull-Rom resampling in effect (filter and prevColor)
    const int32_t* shared = nullptr;  ///< sharedTaps: the tests' outcomes, taken instead of testing
};

/// One pixel's inputs to the tap stage.
struct PixelRef {
    float ppx, ppy, zRef, n0, n1, n2, invZ, invN;
    int32_t refId;
    bool ok;
    int32_t shared;  ///< the pixel's sharedTaps mask (read only with Sources::shared)
};

struct PixelOut {
    float c[3], m[2], h;
    float blur = 0;    ///< resampleBlur: 0 disoccluded, 1 on the 3x3 fallback
    int32_t taps = 0;  ///< the tests' outcomes (output `taps`)
};

// resampleBlur of fractions fx, fy in [0, 1): 2 (fx (1 - fx) + fy (1 - fy)). Both bilinear and
// Catmull-Rom weights reduce to one tap at a fraction of 0 and spread most at 0.5, where a
// resampled detail is attenuated most (Karis 2014 weights the history down there, since the
// attenuation compounds frame after frame).
inline float resampleBlur(float fx, float fy) {
    return 2.f * (fx * (1.f - fx) + fy * (1.f - fy));
}

// Whether the 12 outer taps of the 4x4 footprint at (x0, y0) are consistent, tested in row
// order up to the first that fails (the taps mask records exactly those tested).
template <class Consistent>
bool outerTapsConsistent(int x0, int y0, Consistent& consistent) {
    for (int j = -1; j <= 2; ++j)
        for (int k = -1; k <= 2; ++k)
            if ((j < 0 || j > 1 || k < 0 || k > 1) && !consistent(x0 + k, y0 + j, tapBit(k, j)))
                return false;
    return true;
}

// The Catmull-Rom 4x4 colour at (x0, y0) + (fx, fy), clamped to the inner 2x2 taps' range so
// negative lobes cannot ring.
inline void catmullRomColor(const Sources& S, int x0, int y0, float fx, float fy, float out[3]) {
    const int w = S.w;
    float wx[4], wy[4];
    catmullRomWeights(fx, wx);
    catmullRomWeights(fy, wy);
    for (int c = 0; c < 3; ++c) {
        float s = 0, lo = 3e38f, hi = -3e38f;
        for (int j = 0; j < 4; ++j)
            for (int k = 0; k < 4; ++k) {
                const float v =
                    px::sanitize(S.pc[c][size_t(y0 - 1 + j) * size_t(w) + size_t(x0 - 1 + k)]);
                s = std::fma(wx[k] * wy[j], v, s);
                if (j >= 1 && j <= 2 && k >= 1 && k <= 2) {
                    lo = std::min(lo, v);
                    hi = std::max(hi, v);
                }
            }
        out[c] = px::clamp(s, lo, hi);
    }
}

// The complete per-pixel reprojection (bilinear taps, 3x3 fallback, Catmull-Rom), scalar, with
// bounds checks on every tap. Used for the pixels the tap kernel does not take: taps near the
// image border or off screen, invalid positions, and the (rare) 3x3 fallback. Not inlined: the
// row loop that calls it for those few pixels stays as small as it was in one file.
HWY_NOINLINE PixelOut reprojectPixel(const Sources& S, const PixelRef& P) {
    const int w = S.w, h = S.h;
    const bool shared = S.shared != nullptr;
    int32_t taps = 0;
    // `bit`: the tap's bit in the taps mask, recorded (or, with sharedTaps, read instead).
    auto consistent = [&](int tx, int ty, int bit) -> bool {
        if (shared) return (P.shared >> bit) & 1;
        if (unsigned(tx) >= unsigned(w) || unsigned(ty) >= unsigned(h)) return false;
        const size_t t = size_t(ty) * size_t(w) + size_t(tx);
        const int32_t id = S.pIds ? S.pIds[t] : 0;
        const float dz = std::fabs(P.zRef - px::sanitizeDepth(S.pz[t])) * P.invZ;
        const float nn[3] = {P.n0, P.n1, P.n2};
        float dn2 = 0;
        for (int c = 0; c < 3; ++c) {
            const float dn = nn[c] - px::sanitizeNormal(S.pn[c][t]);
            dn2 = std::fma(dn, dn, dn2);
        }
        const bool ok = (id == P.refId) & !(dz > S.dThr) & (dn2 * (P.invN * P.invN) <= S.nThr2);
        taps |= int32_t(ok) << bit;
        return ok;
    };
    float acc[3] = {0, 0, 0}, accM[2] = {0, 0}, accH = 0, sumW = 0;
    auto addTap = [&](int tx, int ty, float wt) {
        const size_t t = size_t(ty) * size_t(w) + size_t(tx);
        if (S.pc[0])
            for (int c = 0; c < 3; ++c) acc[c] = std::fma(wt, px::sanitize(S.pc[c][t]), acc[c]);
        if (S.pm[0]) {
            accM[0] = std::fma(wt, px::sanitize(S.pm[0][t]), accM[0]);
            accM[1] = std::fma(wt, px::sanitizePositive(S.pm[1][t], 1e32f), accM[1]);
        }
        // The history length's product is rounded before the sum: std::fma(a, b, 0) is that
        // rounded product (the vector kernel computes the same).
        accH += std::fma(wt, S.ph ? px::sanitizePositive(S.ph[t], 1e6f) : 1.f, 0.f);
        sumW += wt;
    };
    int x0 = 0, y0 = 0;
    float fx = 0, fy = 0;
    bool all4 = false, fallback = false;
    if (P.ok) {
        const float bx = P.ppx - 0.5f, by = P.ppy - 0.5f;
        x0 = int(std::floor(bx));
        y0 = int(std::floor(by));
        fx = bx - float(x0);
        fy = by - float(y0);
        const float bw[4] = {(1 - fx) * (1 - fy), fx * (1 - fy), (1 - fx) * fy, fx * fy};
        int nOk = 0;
        for (int k = 0; k < 4; ++k) {
            const int tx = x0 + (k & 1), ty = y0 + (k >> 1);
            if (!consistent(tx, ty, tapBit(k & 1, k >> 1))) continue;
            ++nOk;
            if (bw[k] > 0.f) addTap(tx, ty, bw[k]);
        }
        all4 = nOk == 4;
        if (sumW < 1e-4f) {
            // 3x3 fallback around the pixel containing the position: equal weights.
            acc[0] = acc[1] = acc[2] = accM[0] = accM[1] = accH = sumW = 0;
            const int cx = int(std::floor(P.ppx)), cy = int(std::floor(P.ppy));
            for (int j = -1; j <= 1; ++j)
                for (int k = -1; k <= 1; ++k)
                    if (consistent(cx + k, cy + j, fallbackBit(k, j))) addTap(cx + k, cy + j, 1.f);
            all4 = false;
            fallback = true;
        }
    }
    if (sumW <= 0.f) return {{0, 0, 0}, {0, 0}, 0, 0.f, taps};  // disoccluded
    const float inv = 1.f / sumW;
    PixelOut o{{acc[0] * inv, acc[1] * inv, acc[2] * inv},
               {accM[0] * inv, accM[1] * inv},
               accH * inv,
               fallback ? 1.f : resampleBlur(fx, fy)};
    // Catmull-Rom 4x4 when every tap is consistent (the outer 12 tested in order, up to the
    // first that fails).
    if (S.catmullRom && all4 && x0 >= 1 && y0 >= 1 && x0 + 2 < w && y0 + 2 < h &&
        outerTapsConsistent(x0, y0, consistent))
        catmullRomColor(S, x0, y0, fx, fy, o.c);
    o.taps = taps;
    return o;
}

}  // namespace
}  // namespace kestrel::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#endif  // toggled include guard
