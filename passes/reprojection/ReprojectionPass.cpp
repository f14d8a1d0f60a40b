// Compiled once per SIMD target (hwy/foreach_target.h re-includes this file for each one): the
// whole execute, scalar loops included (they auto-vectorise for the target), lives in
// kestrel::N_<TARGET>; the HWY_ONCE part at the end picks the running CPU's best target.
#include "ReprojectionPass.h"

#include <kestrel/PixelMath.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <type_traits>
#include <vector>

#include "DepthChangeModel.h"

#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "ReprojectionPass.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep
// After foreach_target.h: once per target.
#include <hwy/highway.h>
#include <kestrel/SimdMath.h>

HWY_BEFORE_NAMESPACE();
namespace kestrel::HWY_NAMESPACE {
namespace {

namespace hn = hwy::HWY_NAMESPACE;
/// Per-object transforms of the matrix path: current world -> previous pixel (and previous
/// camera, for the expected previous depth). GAMES202: Screen_{i-1} = P V M_{i-1} M_i^-1 World_i.
struct ObjectTransforms {
    Mat4 toPrevPixel, toPrevCamera;
};

class TransformTable {
public:
    TransformTable(const SceneData& cur, const SceneData& prev) {
        fallback_ = {prev.worldToPixel, prev.worldToCamera};
        for (const auto& [id, o2w] : cur.objectToWorld) {
            auto it = prev.objectToWorld.find(id);
            auto inv = inverse(o2w);
            if (it == prev.objectToWorld.end() || !inv) continue;
            Mat4 motion = it->second * *inv;
            byId_[id] = {prev.worldToPixel * motion, prev.worldToCamera * motion};
        }
        if (!byId_.empty()) {
            lo_ = byId_.begin()->first;
            int64_t span = int64_t(byId_.rbegin()->first) - lo_ + 1;
            if (span <= 65536) {  // dense table: no map lookup per pixel
                dense_.assign(size_t(span), fallback_);
                for (const auto& [id, t] : byId_) dense_[size_t(id - lo_)] = t;
            }
        }
    }
    const ObjectTransforms& fallback() const { return fallback_; }
    const ObjectTransforms& get(int32_t id) const {
        if (!dense_.empty()) {
            int64_t i = int64_t(id) - lo_;
            return i >= 0 && i < int64_t(dense_.size()) ? dense_[size_t(i)] : fallback_;
        }
        auto it = byId_.find(id);
        return it == byId_.end() ? fallback_ : it->second;
    }

private:
    ObjectTransforms fallback_;  // static objects: camera motion only
    std::map<int32_t, ObjectTransforms> byId_;
    std::vector<ObjectTransforms> dense_;
    int32_t lo_ = 0;
};

// Catmull-Rom weights of the 4 taps around a fraction t in [0,1).
inline void catmullRomWeights(float t, float w[4]) {
    const float t2 = t * t, t3 = t2 * t;
    w[0] = -0.5f * t3 + t2 - 0.5f * t;
    w[1] = 1.5f * t3 - 2.5f * t2 + 1.f;
    w[2] = -1.5f * t3 + 2.f * t2 + 0.5f * t;
    w[3] = 0.5f * t3 - 0.5f * t2;
}

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
void rowDerivativesT(const GeomRows& rows, int w, int a, int b, float* __restrict invZ,
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

void rowDerivatives(const GeomRows& g, bool u, bool d, int w, int a, int b, float* invZ,
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

// The complete per-pixel reprojection (bilinear taps, 3x3 fallback, Catmull-Rom), scalar, with
// bounds checks on every tap. Used for the pixels the tap kernel does not take: taps near the
// image border or off screen, invalid positions, and the (rare) 3x3 fallback.
PixelOut reprojectPixel(const Sources& S, const PixelRef& P) {
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
    if (S.catmullRom && all4 && x0 >= 1 && y0 >= 1 && x0 + 2 < w && y0 + 2 < h) {
        // Catmull-Rom 4x4 when every tap is consistent, clamped to the inner 2x2 taps' range
        // so negative lobes cannot ring.
        bool all16 = true;
        for (int j = -1; j <= 2 && all16; ++j)
            for (int k = -1; k <= 2 && all16; ++k)
                if ((j < 0 || j > 1 || k < 0 || k > 1) && !consistent(x0 + k, y0 + j, tapBit(k, j)))
                    all16 = false;
        if (all16) {
            float wx[4], wy[4];
            catmullRomWeights(fx, wx);
            catmullRomWeights(fy, wy);
            for (int c = 0; c < 3; ++c) {
                float s = 0, lo = 3e38f, hi = -3e38f;
                for (int j = 0; j < 4; ++j)
                    for (int k = 0; k < 4; ++k) {
                        const float v = px::sanitize(
                            S.pc[c][size_t(y0 - 1 + j) * size_t(w) + size_t(x0 - 1 + k)]);
                        s = std::fma(wx[k] * wy[j], v, s);
                        if (j >= 1 && j <= 2 && k >= 1 && k <= 2) {
                            lo = std::min(lo, v);
                            hi = std::max(hi, v);
                        }
                    }
                o.c[c] = px::clamp(s, lo, hi);
            }
        }
    }
    o.taps = taps;
    return o;
}

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

// Per-thread scratch, reused across rows, chunks and frames (no allocation in steady state).
struct Scratch {
    std::vector<float> f;
    std::vector<int32_t> i;
    std::vector<uint8_t> b;
    void reserve(size_t nf, size_t ni, size_t nb) {
        if (f.size() < nf) f.resize(nf);
        if (i.size() < ni) i.resize(ni);
        if (b.size() < nb) b.resize(nb);
    }
};

// Index of the first nonzero flag in [from, end), or end (memchr scans 32 bytes at a time).
inline int nextFlag(const uint8_t* flags, int from, int end) {
    if (from >= end) return end;
    const void* p = std::memchr(flags + from, 1, size_t(end - from));
    return p ? int(static_cast<const uint8_t*>(p) - flags) : end;
}
thread_local Scratch tScratch;

/// The pass for this target.
void reproject(FrameContext& ctx, PassIO& io, const ReprojectionPass::Settings& settings) {
    const ReprojectionPass::Declaration& dc = ReprojectionPass::declaration();
    const int w = ctx.extent.width, h = ctx.extent.height;
    const ImageView* outC = io.has(dc.color) ? &io.output(dc.color) : nullptr;
    const ImageView* outM = io.has(dc.moments) ? &io.output(dc.moments) : nullptr;
    const ImageView* outH = io.has(dc.historyLength) ? &io.output(dc.historyLength) : nullptr;
    const ImageView* outB = io.has(dc.resampleBlur) ? &io.output(dc.resampleBlur) : nullptr;
    int32_t* outTaps = io.has(dc.taps) ? io.output(dc.taps).ints() : nullptr;
    const int32_t* shared = io.has(dc.sharedTaps) ? io.input(dc.sharedTaps).ints() : nullptr;
    if (shared && outTaps) {  // resolve leaves taps out then; a harness may still ask for it
        std::copy_n(shared, size_t(w) * size_t(h), outTaps);
        outTaps = nullptr;
    }
    auto zeroAll = [&] {
        for (const ImageView* o : {outC, outM, outH, outB})
            if (o)
                for (int c = 0; c < o->channels(); ++c)
                    std::fill(o->channel(c), o->channel(c) + o->pixels(), 0.f);
        if (outTaps) std::fill(outTaps, outTaps + size_t(w) * size_t(h), 0);
    };
    const bool colorValid = io.has(dc.prevColor), momentsValid = io.has(dc.prevMoments);
    const bool hlValid = io.has(dc.prevHistoryLength);
    // Without last frame's geometry no tap can be tested; without any history there is nothing
    // to reproject: all outputs 0, history length 0.
    if (!io.has(dc.prevDepth) || !io.has(dc.prevNormal) || (!colorValid && !momentsValid)) {
        zeroAll();
        return;
    }
    const ImageView& depth = io.input(dc.depth);
    const ImageView& normal = io.input(dc.normal);
    const ImageView& pDepth = io.input(dc.prevDepth);
    const ImageView& pNormal = io.input(dc.prevNormal);
    const bool useIds = io.has(dc.objectId) && io.has(dc.prevObjectId);
    const int32_t* curIds = io.has(dc.objectId) ? io.input(dc.objectId).ints() : nullptr;
    const int32_t* ids = useIds ? curIds : nullptr;
    const ImageView* motion = io.has(dc.motion) ? &io.input(dc.motion) : nullptr;
    const ImageView* position = io.has(dc.position) ? &io.input(dc.position) : nullptr;
    const bool matrices = !motion && position && ctx.scene && ctx.previousScene &&
                          ctx.scene->hasCamera && ctx.previousScene->hasCamera;
    std::optional<TransformTable> table;
    if (matrices) table.emplace(*ctx.scene, *ctx.previousScene);

    Sources S;
    S.w = w;
    S.h = h;
    S.pz = pDepth.channel(0);
    for (int c = 0; c < 3; ++c) S.pn[c] = pNormal.channel(c);
    S.pIds = useIds ? io.input(dc.prevObjectId).ints() : nullptr;
    if (colorValid)
        for (int c = 0; c < 3; ++c) S.pc[c] = io.input(dc.prevColor).channel(c);
    if (momentsValid)
        for (int c = 0; c < 2; ++c) S.pm[c] = io.input(dc.prevMoments).channel(c);
    if (hlValid) S.ph = io.input(dc.prevHistoryLength).channel(0);
    S.dThr = settings.depthThreshold;
    S.nThr2 = settings.normalThreshold * settings.normalThreshold;
    S.catmullRom = settings.catmullRom && colorValid;
    S.shared = shared;
    // Tap margin of the tap kernel around (x0, y0): Catmull-Rom reads x0-1..x0+2.
    const bool cr = S.catmullRom;
    // Infinite thresholds (geometryTests off): no tap can fail the depth or normal test, so
    // neither the derivatives nor the tests are computed; with sharedTaps no test is.
    const bool geometry = !shared && (std::isfinite(S.dThr) || std::isfinite(S.nThr2));
    const int lo = cr ? 1 : 0, hi = cr ? 2 : 1;
    // With motion vectors only, the depth a static surface had last frame comes from a camera
    // model fitted to this frame's correspondences (DepthChangeModel.h); the identity otherwise.
    DepthChangeModel depthChange;
    if (motion && settings.cameraDepth && geometry && std::isfinite(S.dThr)) {
        const DepthChangeInputs fit{w,
                                    h,
                                    depth.channel(0),
                                    motion->channel(0),
                                    motion->channel(1),
                                    ids,
                                    pDepth.channel(0),
                                    S.pIds,
                                    S.dThr,
                                    settings.depthPrecision};
        depthChange = fitDepthChange(fit);
    }

    ctx.parallelRows(h, [&](int ya, int yb) {
        // Local copies: int stores to the scratch rows could otherwise alias the captured
        // extent, and the row loops would not vectorise.
        const int w = S.w, h = S.h;
        // Row scratch: float rows (derivatives, positions, fractions, weights, output sinks,
        // this frame's sanitised geometry) and int rows (tap offsets, flags, ids), a cache
        // line of padding apart.
        constexpr int kF = 41, kI = 6, kPad = 16, kTile = 256;
        const size_t ws = size_t(w) + kPad;
        Scratch& sc = tScratch;
        sc.reserve(ws * kF, ws * kI, size_t(w));
        float* f = sc.f.data();
        auto frow = [&](int k) { return f + size_t(k) * ws; };
        float *rInvZ = frow(0), *rInvN = frow(1), *rn0 = frow(2), *rn1 = frow(3), *rn2 = frow(4),
              *rZRef = frow(5), *rPpx = frow(6), *rPpy = frow(7), *rFx = frow(8), *rFy = frow(9),
              *rSumW = frow(10);
        float* sink[6] = {frow(11), frow(12), frow(13), frow(14), frow(15), frow(16)};
        float *bw[4] = {frow(17), frow(18), frow(19), frow(20)},
              *wx[4] = {frow(21), frow(22), frow(23), frow(24)},
              *wy[4] = {frow(25), frow(26), frow(27), frow(28)};
        int32_t* iw = sc.i.data();
        auto irow = [&](int k) { return iw + size_t(k) * ws; };
        int32_t *rDx = irow(0), *rDy = irow(1), *rFast = irow(2), *rRefId = irow(3), *rOk = irow(4),
                *zeroIds = irow(5);
        // This frame's sanitised depth and normal, rows y-1..y+1 in a ring of three slots
        // (each element sanitised once, not once per derivative that reads it).
        auto geomSlot = [&](int row, int plane) { return frow(29 + (row % 3) * 4 + plane); };
        auto sanitizeGeom = [&](int row) {
            const float* z = depth.row(0, row);
            float* zo = geomSlot(row, 0);
            for (int x = 0; x < w; ++x) zo[x] = px::sanitizeDepth(z[x]);
            if (!geometry) return;  // normals serve only the tests
            for (int c = 0; c < 3; ++c) {
                const float* n = normal.row(c, row);
                float* no = geomSlot(row, 1 + c);
                for (int x = 0; x < w; ++x) no[x] = px::sanitizeNormal(n[x]);
            }
        };
        if (ya > 0) sanitizeGeom(ya - 1);
        sanitizeGeom(ya);
        uint8_t* redo = sc.b.data();  // per-pixel recomputation
        std::fill(zeroIds, zeroIds + w, 0);

        for (int y = ya; y < yb; ++y) {
            const bool u = y > 0, d = y + 1 < h;
            const int yu = u ? y - 1 : y, yd = d ? y + 1 : y;  // absent neighbours are not used
            if (d) sanitizeGeom(y + 1);
            GeomRows g;
            g.depthStep = settings.depthPrecision;
            for (int j = 0; j < 3; ++j) {
                const int yy = j == 0 ? y : j == 1 ? yu : yd;
                g.z[j] = geomSlot(yy, 0);
                for (int c = 0; c < 3; ++c) g.n[c][j] = geomSlot(yy, 1 + c);
            }
            const size_t rowStart = size_t(y) * size_t(w);
            const float* zRow = geomSlot(y, 0);  // sanitised (sanitizeDepth is idempotent)
            const int32_t* refIds = ids ? ids + rowStart : zeroIds;
            float *oc[3], *om[2], *oh;  // output rows (absent outputs: scratch sinks)
            for (int c = 0; c < 3; ++c) oc[c] = outC ? outC->row(c, y) : sink[c];
            for (int c = 0; c < 2; ++c) om[c] = outM ? outM->row(c, y) : sink[3 + c];
            oh = outH ? outH->row(0, y) : sink[5];
            const RowTerms R{rZRef,
                             rn0,
                             rn1,
                             rn2,
                             rInvZ,
                             rInvN,
                             {bw[0], bw[1], bw[2], bw[3]},
                             {wx[0], wx[1], wx[2], wx[3]},
                             {wy[0], wy[1], wy[2], wy[3]},
                             rRefId,
                             rSumW,
                             {oc[0], oc[1], oc[2]},
                             {om[0], om[1]},
                             oh,
                             outC != nullptr,
                             outM != nullptr,
                             outH != nullptr,
                             outTaps ? outTaps + rowStart : nullptr,
                             shared ? shared + rowStart : nullptr};
            // The row in tiles of kTile pixels (the last one takes the remainder): each stage's
            // slice of the row scratch then stays in the L1 cache from one stage to the next.
            // Rows narrower than a vector are left to reprojectPixel (all rows without FMA).
            const bool vectors = kTapKernel && w >= int(hn::Lanes(DF()));
            for (int a = 0, b = 0; a < w; a = b) {
                b = w - a < 2 * kTile ? w : a + kTile;
                if (geometry) {
                    rowDerivatives(g, u, d, w, a, b, rInvZ, rInvN, rn0, rn1, rn2);
                } else {  // reprojectPixel's tests then compare 0 with infinite thresholds
                    for (float* r : {rInvZ, rInvN, rn0, rn1, rn2}) std::fill(r + a, r + b, 0.f);
                }
                // Previous-frame position in continuous pixel coordinates (centres at +0.5);
                // rOk holds 0 where the position is unusable (no surface on the matrix path).
                if (motion) {
                    const float *mx = motion->row(0, y), *my = motion->row(1, y);
                    const float fy0 = float(y) + 0.5f, rowTerm = depthChange.rowTerm(y);
#pragma GCC ivdep
                    for (int x = a; x < b; ++x) {
                        rPpx[x] = (float(x) + 0.5f) + mx[x];
                        rPpy[x] = fy0 + my[x];
                        const float z = px::sanitizeDepth(zRow[x]);
                        rZRef[x] = z < kBackgroundDepth ? depthChange.predict(z, x, rowTerm) : z;
                        rOk[x] = 1;
                    }
                } else if (matrices) {
                    for (int x = a; x < b; ++x) {
                        float ppx = float(x) + 0.5f, ppy = float(y) + 0.5f;
                        float zRef = px::sanitizeDepth(zRow[x]);
                        bool ok = true;
                        const int32_t id = curIds ? curIds[rowStart + size_t(x)] : 0;
                        if (zRef >= kBackgroundDepth || (curIds && id == kBackgroundId)) {
                            ok = false;  // no surface position to reproject
                        } else {
                            const ObjectTransforms& t = curIds ? table->get(id) : table->fallback();
                            Vec3 p{position->at(0, x, y), position->at(1, x, y),
                                   position->at(2, x, y)};
                            Vec4 s = t.toPrevPixel.transformPoint(p);
                            Vec4 c = t.toPrevCamera.transformPoint(p);
                            ok = s.w > 1e-20f;
                            if (ok) {
                                ppx = s.x / s.w;
                                ppy = s.y / s.w;
                                zRef = -c.z;  // the point's depth last frame (camera looks down -Z)
                            }
                        }
                        rPpx[x] = ppx;
                        rPpy[x] = ppy;
                        rZRef[x] = zRef;
                        rOk[x] = ok;
                    }
                } else {
                    const float fy0 = float(y) + 0.5f;
#pragma GCC ivdep
                    for (int x = a; x < b; ++x) {
                        rPpx[x] = float(x) + 0.5f;
                        rPpy[x] = fy0;
                        rZRef[x] = px::sanitizeDepth(zRow[x]);
                        rOk[x] = 1;
                    }
                }
                // Integer tap offsets and bilinear fractions; rFast: the tap kernel can take the
                // pixel (valid position, every tap inside the image).
#pragma GCC ivdep
                for (int x = a; x < b; ++x) {
                    const float ppx = rPpx[x], ppy = rPpy[x];
                    // NaN, Inf or absurd positions: disoccluded (also guards the int conversions).
                    const bool ok =
                        (rOk[x] != 0) & (std::fabs(ppx) < 1e7f) & (std::fabs(ppy) < 1e7f);
                    const float bx = ok ? ppx - 0.5f : 0.f, by = ok ? ppy - 0.5f : 0.f;
                    const int x0 = int(std::floor(bx)), y0 = int(std::floor(by));
                    rFx[x] = bx - float(x0);
                    rFy[x] = by - float(y0);
                    rDx[x] = x0 - x;
                    rDy[x] = y0 - y;
                    rFast[x] = ok & (x0 - lo >= 0) & (x0 + hi < w) & (y0 - lo >= 0) & (y0 + hi < h);
                    rRefId[x] = refIds[x];
                    rOk[x] = ok;
                }

                // Bilinear (and Catmull-Rom) weights of every pixel, then the tap kernel.
#pragma GCC ivdep
                for (int x = a; x < b; ++x) {
                    const float fx = rFx[x], fy = rFy[x];
                    bw[0][x] = (1 - fx) * (1 - fy);
                    bw[1][x] = fx * (1 - fy);
                    bw[2][x] = (1 - fx) * fy;
                    bw[3][x] = fx * fy;
                }
                if (cr) {
#pragma GCC ivdep
                    for (int x = a; x < b; ++x) {
                        float cx[4], cy[4];
                        catmullRomWeights(rFx[x], cx);
                        catmullRomWeights(rFy[x], cy);
                        for (int k = 0; k < 4; ++k) {
                            wx[k][x] = cx[k];
                            wy[k][x] = cy[k];
                        }
                    }
                }
                if (!vectors)
                    std::fill(rFast + a, rFast + b, 0);
                else if (shared)
                    cr ? tapRow<true, false, TapMode::Shared>(S, R, y, a, b, rFast, rDx, rDy)
                       : tapRow<false, false, TapMode::Shared>(S, R, y, a, b, rFast, rDx, rDy);
                else if (outTaps)
                    tapRows<TapMode::Record>(S, R, y, a, b, rFast, rDx, rDy, cr, geometry);
                else
                    tapRows<TapMode::Test>(S, R, y, a, b, rFast, rDx, rDy, cr, geometry);
            }
            // Everything else, and the kernel's 3x3-fallback pixels, per pixel.
#pragma GCC ivdep
            for (int x = 0; x < w; ++x) redo[x] = (rFast[x] == 0) | (rSumW[x] < 1e-4f);
            // resampleBlur where the tap kernel's result is kept (its weight sum is at least
            // 1e-4 there: not disoccluded) from the fractions; reprojectPixel's elsewhere.
            float* ob = outB ? outB->row(0, y) : nullptr;
            if (ob)
                for (int x = 0; x < w; ++x) ob[x] = redo[x] ? 0.f : resampleBlur(rFx[x], rFy[x]);
            for (int x = nextFlag(redo, 0, w); x < w; x = nextFlag(redo, x + 1, w)) {
                const PixelRef P{rPpx[x],
                                 rPpy[x],
                                 rZRef[x],
                                 rn0[x],
                                 rn1[x],
                                 rn2[x],
                                 rInvZ[x],
                                 rInvN[x],
                                 rRefId[x],
                                 rOk[x] != 0,
                                 shared ? shared[rowStart + size_t(x)] : 0};
                const PixelOut o = reprojectPixel(S, P);
                if (outTaps) outTaps[rowStart + size_t(x)] = o.taps;
                for (int c = 0; c < 3; ++c) oc[c][x] = o.c[c];
                for (int c = 0; c < 2; ++c) om[c][x] = o.m[c];
                oh[x] = o.h;
                if (ob) ob[x] = o.blur;
            }
        }
    });
}

}  // namespace
}  // namespace kestrel::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace kestrel {
namespace {
HWY_EXPORT(reproject);
}  // namespace
}  // namespace kestrel

using namespace kestrel;

ReprojectionPass::Declaration::Declaration()
    : kestrel::Declaration<Params>(
          "Reprojection",
          "Reprojects last frame's colour, moments and history length into this frame:"
          " position from motion vectors, else world position + per-object and camera"
          " matrices, else identity; 2x2 bilinear taps with depth/normal/id consistency"
          " tests, 3x3 fallback, else disocclusion (historyLength 0). Optional Catmull-Rom"
          " colour resampling for TAA histories.") {
    depth = input("depth", Format::Float, "linear view depth");
    normal = input("normal", Format::Float3, "world-space normal");
    objectId =
        optionalInput("objectId", Format::Int32, "object id (taps on another object are rejected)");
    motion = optionalInput("motion", Format::Float2, "screen motion to the previous frame, pixels");
    position = optionalInput("position", Format::Float3, "world position (matrix reprojection)");
    prevDepth = historyInput("prevDepth", Format::Float, "last frame's depth");
    prevNormal = historyInput("prevNormal", Format::Float3, "last frame's normal");
    prevObjectId = historyInput("prevObjectId", Format::Int32, "last frame's object id");
    prevColor = historyInput("prevColor", Format::Float3, "last frame's colour history");
    prevMoments = historyInput("prevMoments", Format::Float2, "last frame's moments history");
    prevHistoryLength =
        historyInput("prevHistoryLength", Format::Float, "last frame's history length");
    sharedTaps = optionalInput("sharedTaps", Format::Int32,
                               "another Reprojection's `taps` over the same geometry, motion and "
                               "thresholds (the specular chain takes the diffuse chain's): its "
                               "outcomes replace this pass's consistency tests, which are then not "
                               "run (a bilinear pass's taps hold no outer taps: Catmull-Rom then "
                               "resamples bilinearly)");
    color = output("color", Format::Float3, "reprojected colour (0 where disoccluded)");
    moments = output("moments", Format::Float2, "reprojected moments (0 where disoccluded)");
    historyLength = output("historyLength", Format::Float,
                           "reprojected history length, 0 where disoccluded or without valid "
                           "history; when prevHistoryLength is not fed, 1 where the reprojection "
                           "succeeded");
    resampleBlur = output("resampleBlur", Format::Float,
                          "how much resampling the history blurs it, in [0, 1]: 2 (fx (1 - fx) + "
                          "fy (1 - fy)) of the reprojected position's fractions fx, fy between "
                          "pixel centres (0 on a centre, 1 midway between four), 1 on the 3x3 "
                          "fallback, 0 where disoccluded (TAA weights the history down by it, "
                          "Karis 2014)");
    taps = output("taps", Format::Int32,
                  "which taps passed the consistency tests, a bit per tap (the 4x4 Catmull-Rom "
                  "footprint, the 3x3 fallback), for another reprojection's sharedTaps");
    param("filter", &Params::filter, {"bilinear", "catmullrom"},
          "colour resampling: bilinear (SVGF) or Catmull-Rom 4x4 (sharp, for TAA)");
    param("depthThreshold", &Params::depthThreshold, 0.0, 1e6,
          "max |z_expected - z_prev| / (fwidth(z) + 0.01) of a consistent tap");
    param("depthPrediction", &Params::depthPrediction, {"camera", "none"},
          "z_expected with motion vectors: camera (z_prev = z (a u + b v + c) + d, a pinhole "
          "camera's rigid motion fitted per frame to the motion vectors' correspondences, so a "
          "dollying camera keeps the history of surfaces facing it) or none (z itself, SVGF's "
          "test); the matrix path uses the matrices");
    param("normalThreshold", &Params::normalThreshold, 0.0, 1e6,
          "max |n - n_prev| / (fwidth(n) + 0.01) of a consistent tap");
    param("geometryTests", &Params::geometryTests,
          "the depth and normal tests (the object id and screen bounds are always tested); off "
          "for TAA histories on jittered G-buffers (a pixel filter wider than a pixel), where "
          "each frame's depth and normal are another sample of the footprint, the tests reject "
          "the edges TAA exists to accumulate, and TAA's neighbourhood clip rejects stale "
          "history instead (Karis 2014)");
}

const ReprojectionPass::Declaration& ReprojectionPass::declaration() {
    static const Declaration d;
    return d;
}

namespace {
ReprojectionPass::Settings settingsOf(const ReprojectionPass::Params& p) {
    // Without the geometry tests every tap passes them: an infinite threshold is passed by any
    // finite distance (and a NaN normal still fails, as with the tests).
    constexpr float kNoTest = std::numeric_limits<float>::infinity();
    return {p.filter == ReprojectionPass::Filter::CatmullRom,
            p.depthPrediction == ReprojectionPass::DepthPrediction::Camera,
            p.geometryTests ? p.depthThreshold : kNoTest,
            p.geometryTests ? p.normalThreshold : kNoTest};
}
}  // namespace

ReprojectionPass::ReprojectionPass(const ParamValues& p) : s_(settingsOf(declaration().read(p))) {}

void ReprojectionPass::resolve(ResolveContext& rc) {
    const Declaration& d = declaration();
    if (!rc.isBound(d.prevColor)) rc.setAbsent(d.color, "prevColor is not connected");
    if (!rc.isBound(d.prevMoments)) rc.setAbsent(d.moments, "prevMoments is not connected");
    s_.depthPrecision = depthPrecision(rc);
    if (rc.isBound(d.sharedTaps)) {
        rc.setAbsent(d.taps, "the taps come from sharedTaps");
        rc.note("consistency tests taken from sharedTaps");
    }
    if (rc.isBound(d.motion)) {
        rc.note("reprojecting with motion vectors");
        // World positions serve only the matrix path: not read, so the loader skips them.
        if (rc.isBound(d.position)) rc.ignoreInput(d.position, "motion vectors are given");
    } else if (rc.isBound(d.position))
        rc.note("reprojecting with world positions and matrices");
    else
        rc.note("no motion and no position: identity reprojection (static camera assumed)");
}

void ReprojectionPass::execute(FrameContext& ctx, PassIO& io) {
    HWY_DYNAMIC_DISPATCH(reproject)(ctx, io, s_);
}
#endif  // HWY_ONCE
