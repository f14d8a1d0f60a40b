#include "ReprojectionPass.h"

#include <kestrel/PixelMath.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <map>
#include <memory>
#include <optional>
#include <type_traits>
#include <vector>

using namespace kestrel;

PassDesc ReprojectionPass::describe() {
    PassDesc d("Reprojection",
               "Reprojects last frame's colour, moments and history length into this frame:"
               " position from motion vectors, else world position + per-object and camera"
               " matrices, else identity; 2x2 bilinear taps with depth/normal/id consistency"
               " tests, 3x3 fallback, else disocclusion (historyLength 0). Optional Catmull-Rom"
               " colour resampling for TAA histories.");
    d.input("depth", Format::Float, "linear view depth")
        .input("normal", Format::Float3, "world-space normal")
        .optionalInput("objectId", Format::Int32, "object id (taps on another object are rejected)")
        .optionalInput("motion", Format::Float2, "screen motion to the previous frame, pixels")
        .optionalInput("position", Format::Float3, "world position (matrix reprojection)")
        .historyInput("prevDepth", Format::Float, "last frame's depth")
        .historyInput("prevNormal", Format::Float3, "last frame's normal")
        .historyInput("prevObjectId", Format::Int32, "last frame's object id")
        .historyInput("prevColor", Format::Float3, "last frame's colour history")
        .historyInput("prevMoments", Format::Float2, "last frame's moments history")
        .historyInput("prevHistoryLength", Format::Float, "last frame's history length")
        .output("color", Format::Float3, "reprojected colour (0 where disoccluded)")
        .output("moments", Format::Float2, "reprojected moments (0 where disoccluded)")
        .output("historyLength", Format::Float,
                "reprojected history length, 0 where disoccluded or without valid history; when"
                " prevHistoryLength is not fed, 1 where the reprojection succeeded")
        .paramEnum("filter", "bilinear", {"bilinear", "catmullrom"},
                   "colour resampling: bilinear (SVGF) or Catmull-Rom 4x4 (sharp, for TAA)")
        .paramFloat("depthThreshold", 10.0, 0.0, 1e6,
                    "max |z - z_prev| / (fwidth(z) + 0.01) of a consistent tap")
        .paramFloat("normalThreshold", 16.0, 0.0, 1e6,
                    "max |n - n_prev| / (fwidth(n) + 0.01) of a consistent tap");
    return d;
}

ReprojectionPass::ReprojectionPass(const ParamValues& p)
    : catmullRom_(p.getString("filter") == "catmullrom"),
      depthThreshold_(p.getFloat("depthThreshold")),
      normalThreshold_(p.getFloat("normalThreshold")) {}

void ReprojectionPass::resolve(ResolveContext& rc) {
    if (!rc.isBound("prevColor")) rc.setAbsent("color", "prevColor is not connected");
    if (!rc.isBound("prevMoments")) rc.setAbsent("moments", "prevMoments is not connected");
    if (rc.isBound("motion")) {
        rc.note("reprojecting with motion vectors");
        // World positions serve only the matrix path: not read, so the loader skips them.
        if (rc.isBound("position")) rc.ignoreInput("position", "motion vectors are given");
    } else if (rc.isBound("position"))
        rc.note("reprojecting with world positions and matrices");
    else
        rc.note("no motion and no position: identity reprojection (static camera assumed)");
}

namespace {

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
    const float fwN = std::sqrt(dnx2) + std::sqrt(dny2);
    invZ[x] = 1.f / (fwZ + 1e-2f);
    invN[x] = 1.f / (fwN + 1e-2f);
}

// One row of derivatives: the two end pixels separately, the interior in a loop with fixed
// neighbours (contiguous loads, no selects), which the compiler vectorises.
template <bool U, bool D>
void rowDerivativesT(const GeomRows& rows, int w, float* __restrict invZ, float* __restrict invN,
                     float* __restrict n0, float* __restrict n1, float* __restrict n2) {
    const GeomRows g = rows;  // a local copy: the row pointers stay in registers
    if (w == 1) {
        derivativesAt<false, false, U, D>(g, 0, invZ, invN, n0, n1, n2);
        return;
    }
    derivativesAt<false, true, U, D>(g, 0, invZ, invN, n0, n1, n2);
#pragma GCC ivdep
    for (int x = 1; x < w - 1; ++x) derivativesAt<true, true, U, D>(g, x, invZ, invN, n0, n1, n2);
    derivativesAt<true, false, U, D>(g, w - 1, invZ, invN, n0, n1, n2);
}

void rowDerivatives(const GeomRows& g, bool u, bool d, int w, float* invZ, float* invN, float* n0,
                    float* n1, float* n2) {
    if (u && d)
        rowDerivativesT<true, true>(g, w, invZ, invN, n0, n1, n2);
    else if (u)
        rowDerivativesT<true, false>(g, w, invZ, invN, n0, n1, n2);
    else if (d)
        rowDerivativesT<false, true>(g, w, invZ, invN, n0, n1, n2);
    else
        rowDerivativesT<false, false>(g, w, invZ, invN, n0, n1, n2);
}

// Every plane the taps read, and the parameters of the consistency test.
struct Sources {
    int w = 0, h = 0;
    const float *pz = nullptr, *pn[3] = {};
    const int32_t* pIds = nullptr;  ///< null without ids (every id test passes)
    const float *pc[3] = {}, *pm[2] = {}, *ph = nullptr;  ///< null when not fed
    float dThr = 0, nThr = 0;
    bool catmullRom = false;  ///< Catmull-Rom resampling in effect (filter and prevColor)
};

/// One pixel's inputs to the tap stage.
struct PixelRef {
    float ppx, ppy, zRef, n0, n1, n2, invZ, invN;
    int32_t refId;
    bool ok;
};

struct PixelOut {
    float c[3], m[2], h;
};

// The complete per-pixel reprojection (bilinear taps, 3x3 fallback, Catmull-Rom), scalar, with
// bounds checks on every tap. Used for the pixels the row kernel does not take: taps near the
// image border or off screen, invalid positions, and the (rare) 3x3 fallback.
PixelOut reprojectPixel(const Sources& S, const PixelRef& P) {
    const int w = S.w, h = S.h;
    auto consistent = [&](int tx, int ty) -> bool {
        if (unsigned(tx) >= unsigned(w) || unsigned(ty) >= unsigned(h)) return false;
        const size_t t = size_t(ty) * size_t(w) + size_t(tx);
        const int32_t id = S.pIds ? S.pIds[t] : 0;
        const float dz = std::fabs(P.zRef - px::sanitizeDepth(S.pz[t])) * P.invZ;
        const float nn[3] = {P.n0, P.n1, P.n2};
        float dn2 = 0;
        for (int c = 0; c < 3; ++c) {
            const float dn = nn[c] - px::sanitizeNormal(S.pn[c][t]);
            dn2 += dn * dn;
        }
        return (id == P.refId) & !(dz > S.dThr) & (std::sqrt(dn2) * P.invN <= S.nThr);
    };
    float acc[3] = {0, 0, 0}, accM[2] = {0, 0}, accH = 0, sumW = 0;
    auto addTap = [&](int tx, int ty, float wt) {
        const size_t t = size_t(ty) * size_t(w) + size_t(tx);
        if (S.pc[0])
            for (int c = 0; c < 3; ++c) acc[c] += wt * px::sanitize(S.pc[c][t]);
        if (S.pm[0]) {
            accM[0] += wt * px::sanitize(S.pm[0][t]);
            accM[1] += wt * px::sanitizePositive(S.pm[1][t], 1e32f);
        }
        // The history length's product is rounded before the sum (not fused into an FMA),
        // as the compiler always evaluated `accH += wt * (hist ? h : 1)`; std::fma(a, b, 0)
        // is that rounded product and cannot be contracted further.
        accH += std::fma(wt, S.ph ? px::sanitizePositive(S.ph[t], 1e6f) : 1.f, 0.f);
        sumW += wt;
    };
    int x0 = 0, y0 = 0;
    float fx = 0, fy = 0;
    bool all4 = false;
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
            if (!consistent(tx, ty)) continue;
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
                    if (consistent(cx + k, cy + j)) addTap(cx + k, cy + j, 1.f);
            all4 = false;
        }
    }
    if (sumW <= 0.f) return {{0, 0, 0}, {0, 0}, 0};  // disoccluded
    const float inv = 1.f / sumW;
    PixelOut o{
        {acc[0] * inv, acc[1] * inv, acc[2] * inv}, {accM[0] * inv, accM[1] * inv}, accH * inv};
    if (S.catmullRom && all4 && x0 >= 1 && y0 >= 1 && x0 + 2 < w && y0 + 2 < h) {
        // Catmull-Rom 4x4 when every tap is consistent, clamped to the inner 2x2 taps' range
        // so negative lobes cannot ring.
        bool all16 = true;
        for (int j = -1; j <= 2 && all16; ++j)
            for (int k = -1; k <= 2 && all16; ++k)
                if ((j < 0 || j > 1 || k < 0 || k > 1) && !consistent(x0 + k, y0 + j))
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
                        s += wx[k] * wy[j] * v;
                        if (j >= 1 && j <= 2 && k >= 1 && k <= 2) {
                            lo = std::min(lo, v);
                            hi = std::max(hi, v);
                        }
                    }
                o.c[c] = px::clamp(s, lo, hi);
            }
        }
    }
    return o;
}

// The row kernel: pixels x in [a, b) of one row whose taps all lie at the same integer offset
// (x0 = x + dx, y0 = y + dy) and inside the image (rows y0-1..y0+2 and columns x0-1..x0+2 for
// Catmull-Rom, else y0..y0+1 and x0..x0+1). Loads are then contiguous and need no bounds
// checks, so each stage below is a branch-free loop the compiler vectorises across x. The work
// is split into small stages (consistency masks, weights, one pass per output plane) so each
// loop keeps few pointers live. Taps are accumulated with selects in the scalar order (a
// skipped tap leaves the sums untouched), so every result is bit-identical to reprojectPixel.
// Pixels whose bilinear weight sum is below the 3x3-fallback threshold are recomputed by
// reprojectPixel afterwards.
//
// Consistency bits: bit 4 * j + (k + 1) for the tap at column x0 + k, row y0 - 1 + j
// (k, j - 1 in -1..2); the bilinear taps are bits 5, 6 (row y0) and 9, 10 (row y0 + 1).
constexpr int kBit00 = 5, kBit10 = 6, kBit01 = 9, kBit11 = 10;

/// This row's per-pixel reference values and the kernel's per-pixel scratch.
struct KernelRow {
    const float *zRef, *n0, *n1, *n2, *invZ, *invN, *fx, *fy;
    const int32_t* refId;
    int32_t* mask;
    float *sumW, *inv, *bw[4], *wx[4], *wy[4];
};

// Consistency of taps at columns x0 + k, k = K0 .. K0 + NK - 1, in one previous-frame row
// (SVGF, Falcor's isReprjValid), OR-ed into the mask at bit `bit0 + k - K0`. z and pn* are
// that row's sanitised depth and normal (see sanitizeSegment).
template <int K0, int NK>
void consistencyRow(int a, int b, int dx, int bit0, const float* __restrict z,
                    const float* __restrict pn0, const float* __restrict pn1,
                    const float* __restrict pn2, const int32_t* __restrict ids,
                    const KernelRow& row, float dThr, float nThr) {
    const float *zRef = row.zRef, *n0 = row.n0, *n1 = row.n1, *n2 = row.n2, *invZ = row.invZ,
                *invN = row.invN;
    const int32_t* refId = row.refId;
    int32_t* mask = row.mask;
#pragma GCC ivdep
    for (int x = a; x < b; ++x) {
        const float zR = zRef[x], c0 = n0[x], c1 = n1[x], c2 = n2[x], iz = invZ[x], in = invN[x];
        const int32_t rid = refId[x];
        int32_t m = mask[x];
#pragma GCC unroll 4
        for (int k = 0; k < NK; ++k) {
            const int t = x + dx + K0 + k;
            const float dz = std::fabs(zR - z[t]) * iz;
            const float d0 = c0 - pn0[t];
            const float d1 = c1 - pn1[t];
            const float d2 = c2 - pn2[t];
            float dn2 = 0;
            dn2 += d0 * d0;
            dn2 += d1 * d1;
            dn2 += d2 * d2;
            const bool ok = (ids[t] == rid) & !(dz > dThr) & (std::sqrt(dn2) * in <= nThr);
            m |= int32_t(ok) << (bit0 + k);
        }
        mask[x] = m;
    }
}

// Bilinear weights, their sum over the consistent taps with positive weight (in tap order),
// its reciprocal, and (Catmull-Rom) the 4 + 4 separable weights.
template <bool CR>
void weightsRow(int a, int b, const KernelRow& row) {
    const float *fxs = row.fx, *fys = row.fy;
    const int32_t* mask = row.mask;
    float *sumW = row.sumW, *inv = row.inv, *bw0 = row.bw[0], *bw1 = row.bw[1], *bw2 = row.bw[2],
          *bw3 = row.bw[3];
#pragma GCC ivdep
    for (int x = a; x < b; ++x) {
        const float fx = fxs[x], fy = fys[x];
        const int32_t m = mask[x];
        const float w0 = (1 - fx) * (1 - fy), w1 = fx * (1 - fy), w2 = (1 - fx) * fy, w3 = fx * fy;
        float sw = 0;
        sw = ((m & (1 << kBit00)) != 0) & (w0 > 0.f) ? sw + w0 : sw;
        sw = ((m & (1 << kBit10)) != 0) & (w1 > 0.f) ? sw + w1 : sw;
        sw = ((m & (1 << kBit01)) != 0) & (w2 > 0.f) ? sw + w2 : sw;
        sw = ((m & (1 << kBit11)) != 0) & (w3 > 0.f) ? sw + w3 : sw;
        bw0[x] = w0;
        bw1[x] = w1;
        bw2[x] = w2;
        bw3[x] = w3;
        sumW[x] = sw;
        inv[x] = 1.f / sw;  // sw < 1e-4: recomputed by reprojectPixel
    }
    if constexpr (CR) {
        float *wx0 = row.wx[0], *wx1 = row.wx[1], *wx2 = row.wx[2], *wx3 = row.wx[3];
        float *wy0 = row.wy[0], *wy1 = row.wy[1], *wy2 = row.wy[2], *wy3 = row.wy[3];
#pragma GCC ivdep
        for (int x = a; x < b; ++x) {
            float wx[4], wy[4];
            catmullRomWeights(fxs[x], wx);
            catmullRomWeights(fys[x], wy);
            wx0[x] = wx[0];
            wx1[x] = wx[1];
            wx2[x] = wx[2];
            wx3[x] = wx[3];
            wy0[x] = wy[0];
            wy1[x] = wy[1];
            wy2[x] = wy[2];
            wy3[x] = wy[3];
        }
    }
}

enum class Sanitize { Depth, Normal, Radiance, Moment1, Moment2, Length };

// Sanitises columns [c0, c1) of a previous-frame row into the same columns of `dst` once per
// run, so the stages below read each tap's sanitised value instead of sanitising it again for
// every pixel and tap that reads it (16 taps per pixel for Catmull-Rom). Columns from `w` on
// (read only by the stages' rounding up to whole vectors, never used) become 0.
template <Sanitize S>
void sanitizeSegment(int c0, int c1, int w, const float* __restrict src, float* __restrict dst) {
    const int cv = std::min(c1, w);
#pragma GCC ivdep
    for (int i = c0; i < cv; ++i) {
        const float v = src[i];
        if constexpr (S == Sanitize::Depth) dst[i] = px::sanitizeDepth(v);
        if constexpr (S == Sanitize::Normal) dst[i] = px::sanitizeNormal(v);
        if constexpr (S == Sanitize::Radiance || S == Sanitize::Moment1) dst[i] = px::sanitize(v);
        if constexpr (S == Sanitize::Moment2) dst[i] = px::sanitizePositive(v, 1e32f);
        if constexpr (S == Sanitize::Length) dst[i] = px::sanitizePositive(v, 1e6f);
    }
    for (int i = std::max(cv, c0); i < c1; ++i) dst[i] = 0.f;
}

// The geometry of a previous-frame row (sanitised depth and normal, object ids) for columns
// [c0, c1), in one loop; as sanitizeSegment.
void geometrySegment(int c0, int c1, int w, const float* __restrict z, const float* __restrict n0,
                     const float* __restrict n1, const float* __restrict n2,
                     const int32_t* __restrict ids, float* __restrict zs, float* __restrict ns0,
                     float* __restrict ns1, float* __restrict ns2, int32_t* __restrict idsOut) {
    const int cv = std::min(c1, w);
#pragma GCC ivdep
    for (int i = c0; i < cv; ++i) {
        zs[i] = px::sanitizeDepth(z[i]);
        ns0[i] = px::sanitizeNormal(n0[i]);
        ns1[i] = px::sanitizeNormal(n1[i]);
        ns2[i] = px::sanitizeNormal(n2[i]);
        idsOut[i] = ids ? ids[i] : 0;
    }
    for (int i = std::max(cv, c0); i < c1; ++i) {
        zs[i] = ns0[i] = ns1[i] = ns2[i] = 0.f;
        idsOut[i] = 0;
    }
}

// One output plane: the consistent bilinear taps of the sanitised rows r0 (y0) and r1 (y0 + 1),
// weighted and divided by the weight sum. Length: the history length, whose product is rounded
// before the sum (not fused into an FMA), as the compiler always evaluated
// `accH += wt * (hist ? h : 1)`; std::fma(a, b, 0) is that rounded product and cannot be
// contracted further.
template <bool Length>
void bilinearPlaneRow(int a, int b, int dx, const float* __restrict r0, const float* __restrict r1,
                      const KernelRow& row, float* __restrict out) {
    const float *bw0 = row.bw[0], *bw1 = row.bw[1], *bw2 = row.bw[2], *bw3 = row.bw[3],
                *inv = row.inv;
    const int32_t* mask = row.mask;
    auto add = [](float acc, float wt, float v) __attribute__((always_inline)) {
        if constexpr (Length) return acc + std::fma(wt, v, 0.f);
        return acc + wt * v;
    };
#pragma GCC ivdep
    for (int x = a; x < b; ++x) {
        const int t = x + dx;
        const int32_t m = mask[x];
        const float w0 = bw0[x], w1 = bw1[x], w2 = bw2[x], w3 = bw3[x];
        const float v0 = r0[t], v1 = r0[t + 1], v2 = r1[t], v3 = r1[t + 1];
        float acc = 0;
        acc = ((m & (1 << kBit00)) != 0) & (w0 > 0.f) ? add(acc, w0, v0) : acc;
        acc = ((m & (1 << kBit10)) != 0) & (w1 > 0.f) ? add(acc, w1, v1) : acc;
        acc = ((m & (1 << kBit01)) != 0) & (w2 > 0.f) ? add(acc, w2, v2) : acc;
        acc = ((m & (1 << kBit11)) != 0) & (w3 > 0.f) ? add(acc, w3, v3) : acc;
        out[x] = acc * inv[x];
    }
}

// Catmull-Rom 4x4 of one sanitised colour plane (rows y0-1..y0+2) where all 16 taps are
// consistent, clamped to the inner 2x2 taps' range so negative lobes cannot ring.
void catmullRomPlaneRow(int a, int b, int dx, const float* const* rows, const KernelRow& row,
                        float* __restrict out) {
    const float *q0 = rows[0], *q1 = rows[1], *q2 = rows[2], *q3 = rows[3];
    const float *wx0 = row.wx[0], *wx1 = row.wx[1], *wx2 = row.wx[2], *wx3 = row.wx[3];
    const float *wy0 = row.wy[0], *wy1 = row.wy[1], *wy2 = row.wy[2], *wy3 = row.wy[3];
    const int32_t* mask = row.mask;
#pragma GCC ivdep
    for (int x = a; x < b; ++x) {
        const int t = x + dx - 1;
        const float wx[4] = {wx0[x], wx1[x], wx2[x], wx3[x]};
        const float wy[4] = {wy0[x], wy1[x], wy2[x], wy3[x]};
        const float* q[4] = {q0, q1, q2, q3};
        float s = 0, lo = 3e38f, hi = -3e38f;
#pragma GCC unroll 4
        for (int j = 0; j < 4; ++j)
#pragma GCC unroll 4
            for (int k = 0; k < 4; ++k) {
                const float v = q[j][t + k];
                s += wx[k] * wy[j] * v;
                if (j >= 1 && j <= 2 && k >= 1 && k <= 2) {
                    lo = v < lo ? v : lo;  // std::min(lo, v), std::max(hi, v)
                    hi = hi < v ? v : hi;
                }
            }
        const bool all16 = (mask[x] & 0xffff) == 0xffff;
        out[x] = all16 ? px::clamp(s, lo, hi) : out[x];
    }
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

}  // namespace

void ReprojectionPass::execute(FrameContext& ctx, PassIO& io) {
    const int w = ctx.extent.width, h = ctx.extent.height;
    const ImageView* outC = io.hasOutput("color") ? &io.output("color") : nullptr;
    const ImageView* outM = io.hasOutput("moments") ? &io.output("moments") : nullptr;
    const ImageView* outH = io.hasOutput("historyLength") ? &io.output("historyLength") : nullptr;
    auto zeroAll = [&] {
        for (const ImageView* o : {outC, outM, outH})
            if (o)
                for (int c = 0; c < o->channels(); ++c)
                    std::fill(o->channel(c), o->channel(c) + o->pixels(), 0.f);
    };
    const bool colorValid = io.hasInput("prevColor"), momentsValid = io.hasInput("prevMoments");
    const bool hlValid = io.hasInput("prevHistoryLength");
    // Without last frame's geometry no tap can be tested; without any history there is nothing
    // to reproject: all outputs 0, history length 0.
    if (!io.hasInput("prevDepth") || !io.hasInput("prevNormal") || (!colorValid && !momentsValid)) {
        zeroAll();
        return;
    }
    const ImageView& depth = io.input("depth");
    const ImageView& normal = io.input("normal");
    const ImageView& pDepth = io.input("prevDepth");
    const ImageView& pNormal = io.input("prevNormal");
    const bool useIds = io.hasInput("objectId") && io.hasInput("prevObjectId");
    const int32_t* curIds = io.hasInput("objectId") ? io.input("objectId").ints() : nullptr;
    const int32_t* ids = useIds ? curIds : nullptr;
    const ImageView* motion = io.hasInput("motion") ? &io.input("motion") : nullptr;
    const ImageView* position = io.hasInput("position") ? &io.input("position") : nullptr;
    const bool matrices = !motion && position && ctx.scene && ctx.previousScene &&
                          ctx.scene->hasCamera && ctx.previousScene->hasCamera;
    std::optional<TransformTable> table;
    if (matrices) table.emplace(*ctx.scene, *ctx.previousScene);

    Sources S;
    S.w = w;
    S.h = h;
    S.pz = pDepth.channel(0);
    for (int c = 0; c < 3; ++c) S.pn[c] = pNormal.channel(c);
    S.pIds = useIds ? io.input("prevObjectId").ints() : nullptr;
    if (colorValid)
        for (int c = 0; c < 3; ++c) S.pc[c] = io.input("prevColor").channel(c);
    if (momentsValid)
        for (int c = 0; c < 2; ++c) S.pm[c] = io.input("prevMoments").channel(c);
    if (hlValid) S.ph = io.input("prevHistoryLength").channel(0);
    S.dThr = depthThreshold_;
    S.nThr = normalThreshold_;
    S.catmullRom = catmullRom_ && colorValid;
    // Tap margin of the row kernel around (x0, y0): Catmull-Rom reads x0-1..x0+2.
    const bool cr = S.catmullRom;
    const int lo = cr ? 1 : 0, hi = cr ? 2 : 1;

    ctx.parallelRows(h, [&](int ya, int yb) {
        // Local copies: int stores to the scratch rows could otherwise alias the captured
        // extent, and the row loops would not vectorise.
        const int w = S.w, h = S.h;
        // Row scratch: float rows (derivatives, positions, fractions, kernel weights, output
        // sinks, sanitised previous-frame rows) and int rows (tap offsets, flags, ids, masks).
        // Rows are padded: the stages round runs up to whole vectors (see below).
        constexpr int kF = 83, kI = 11, kPad = 32;
        const size_t ws = size_t(w) + kPad;
        Scratch& sc = tScratch;
        sc.reserve(ws * kF, ws * kI, size_t(w) * 2);
        float* f = sc.f.data();
        auto frow = [&](int k) { return f + size_t(k) * ws; };
        float *rInvZ = frow(0), *rInvN = frow(1), *rn0 = frow(2), *rn1 = frow(3), *rn2 = frow(4),
              *rZRef = frow(5), *rPpx = frow(6), *rPpy = frow(7), *rFx = frow(8), *rFy = frow(9),
              *rSumW = frow(10), *rInv = frow(11);
        float* sink[6] = {frow(13), frow(14), frow(15), frow(16), frow(17), frow(18)};
        int32_t* iw = sc.i.data();
        auto irow = [&](int k) { return iw + size_t(k) * ws; };
        int32_t *rDx = irow(0), *rDy = irow(1), *rFast = irow(2), *rRefId = irow(3), *rOk = irow(4),
                *rMask = irow(5), *zeroIds = irow(6);
        int32_t* idsS[4] = {irow(7), irow(8), irow(9), irow(10)};  // the run's rows' ids
        KernelRow K{rZRef,
                    rn0,
                    rn1,
                    rn2,
                    rInvZ,
                    rInvN,
                    rFx,
                    rFy,
                    rRefId,
                    rMask,
                    rSumW,
                    rInv,
                    {frow(19), frow(20), frow(21), frow(22)},
                    {frow(23), frow(24), frow(25), frow(26)},
                    {frow(27), frow(28), frow(29), frow(30)}};
        // Sanitised previous-frame rows y0-1..y0+2 of the current run (same column indices as
        // the planes): depth, normal, colour, moments, history length.
        float *zs[4], *ns[3][4], *cs[3][4], *ms[2][4], *hs[4];
        for (int j = 0; j < 4; ++j) {
            zs[j] = frow(31 + j);
            hs[j] = frow(35 + j);
            for (int c = 0; c < 3; ++c) ns[c][j] = frow(39 + 4 * c + j);
            for (int c = 0; c < 3; ++c) cs[c][j] = frow(51 + 4 * c + j);
            for (int c = 0; c < 2; ++c) ms[c][j] = frow(63 + 4 * c + j);
        }
        // This frame's sanitised depth and normal, rows y-1..y+1 in a ring of three slots
        // (each element sanitised once, not once per derivative that reads it).
        auto geomSlot = [&](int row, int plane) { return frow(71 + (row % 3) * 4 + plane); };
        auto sanitizeGeom = [&](int row) {
            const float* z = depth.row(0, row);
            float* zo = geomSlot(row, 0);
            for (int x = 0; x < w; ++x) zo[x] = px::sanitizeDepth(z[x]);
            for (int c = 0; c < 3; ++c) {
                const float* n = normal.row(c, row);
                float* no = geomSlot(row, 1 + c);
                for (int x = 0; x < w; ++x) no[x] = px::sanitizeNormal(n[x]);
            }
        };
        if (ya > 0) sanitizeGeom(ya - 1);
        sanitizeGeom(ya);
        uint8_t *brk = sc.b.data(), *redo = brk + w;  // run starts, per-pixel recomputation
        std::fill(zeroIds, zeroIds + w, 0);

        for (int y = ya; y < yb; ++y) {
            const bool u = y > 0, d = y + 1 < h;
            const int yu = u ? y - 1 : y, yd = d ? y + 1 : y;  // absent neighbours are not used
            if (d) sanitizeGeom(y + 1);
            GeomRows g;
            for (int j = 0; j < 3; ++j) {
                const int yy = j == 0 ? y : j == 1 ? yu : yd;
                g.z[j] = geomSlot(yy, 0);
                for (int c = 0; c < 3; ++c) g.n[c][j] = geomSlot(yy, 1 + c);
            }
            rowDerivatives(g, u, d, w, rInvZ, rInvN, rn0, rn1, rn2);
            const size_t rowStart = size_t(y) * size_t(w);
            const float* zRow = geomSlot(y, 0);  // sanitised (sanitizeDepth is idempotent)
            // Previous-frame position in continuous pixel coordinates (centres at +0.5);
            // rOk holds 0 where the position is unusable (no surface on the matrix path).
            if (motion) {
                const float *mx = motion->row(0, y), *my = motion->row(1, y);
                const float fy0 = float(y) + 0.5f;
#pragma GCC ivdep
                for (int x = 0; x < w; ++x) {
                    rPpx[x] = (float(x) + 0.5f) + mx[x];
                    rPpy[x] = fy0 + my[x];
                    rZRef[x] = px::sanitizeDepth(zRow[x]);
                    rOk[x] = 1;
                }
            } else if (matrices) {
                for (int x = 0; x < w; ++x) {
                    float ppx = float(x) + 0.5f, ppy = float(y) + 0.5f;
                    float zRef = px::sanitizeDepth(zRow[x]);
                    bool ok = true;
                    const int32_t id = curIds ? curIds[rowStart + size_t(x)] : 0;
                    if (zRef >= kBackgroundDepth || (curIds && id == kBackgroundId)) {
                        ok = false;  // no surface position to reproject
                    } else {
                        const ObjectTransforms& t = curIds ? table->get(id) : table->fallback();
                        Vec3 p{position->at(0, x, y), position->at(1, x, y), position->at(2, x, y)};
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
                for (int x = 0; x < w; ++x) {
                    rPpx[x] = float(x) + 0.5f;
                    rPpy[x] = fy0;
                    rZRef[x] = px::sanitizeDepth(zRow[x]);
                    rOk[x] = 1;
                }
            }
            // Integer tap offsets and bilinear fractions; rFast: the row kernel can take the
            // pixel (valid position, every tap inside the image).
            const int32_t* refIds = ids ? ids + rowStart : zeroIds;
#pragma GCC ivdep
            for (int x = 0; x < w; ++x) {
                const float ppx = rPpx[x], ppy = rPpy[x];
                // NaN, Inf or absurd positions: disoccluded (also guards the int conversions).
                const bool ok = (rOk[x] != 0) & (std::fabs(ppx) < 1e7f) & (std::fabs(ppy) < 1e7f);
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

            float *oc[3], *om[2], *oh;  // output rows (absent outputs: scratch sinks)
            for (int c = 0; c < 3; ++c) oc[c] = outC ? outC->row(c, y) : sink[c];
            for (int c = 0; c < 2; ++c) om[c] = outM ? outM->row(c, y) : sink[3 + c];
            oh = outH ? outH->row(0, y) : sink[5];

            // Runs of pixels with one tap offset: brk marks where a run starts.
            brk[0] = 1;
#pragma GCC ivdep
            for (int x = 1; x < w; ++x)
                brk[x] =
                    (rFast[x] != rFast[x - 1]) | (rDx[x] != rDx[x - 1]) | (rDy[x] != rDy[x - 1]);
            for (int x = 0; x < w;) {
                const int e = nextFlag(brk, x + 1, w);
                if (rFast[x]) {
                    const int dx = rDx[x], dy = rDy[x];
                    size_t o[4];                 // previous-frame rows y0-1 .. y0+2
                    for (int j = 0; j < 4; ++j)  // outside the kernel's margin: never read
                        o[j] = size_t(std::clamp(y + dy - 1 + j, 0, h - 1)) * size_t(w);
                    // Every stage runs over [x, eV), the run rounded up to whole vectors (no
                    // scalar remainder loops); the extra lanes read padded scratch and write
                    // pixels to the right that a later run or the per-pixel pass overwrites.
                    const int up = x + ((e - x + 7) & ~7), eV = up <= w ? up : e;
                    std::fill(rMask + x, rMask + eV, 0);
                    // Columns the run's taps read (rounded up likewise), and its rows
                    // (Catmull-Rom: all four).
                    const int c0 = x + dx - lo, c1 = c0 + ((eV + dx + hi - c0 + 7) & ~7);
                    const int j0 = cr ? 0 : 1, j1 = cr ? 3 : 2;
                    for (int j = j0; j <= j1; ++j) {
                        geometrySegment(c0, c1, w, S.pz + o[j], S.pn[0] + o[j], S.pn[1] + o[j],
                                        S.pn[2] + o[j], S.pIds ? S.pIds + o[j] : nullptr, zs[j],
                                        ns[0][j], ns[1][j], ns[2][j], idsS[j]);
                        if (cr)
                            consistencyRow<-1, 4>(x, eV, dx, 4 * j, zs[j], ns[0][j], ns[1][j],
                                                  ns[2][j], idsS[j], K, S.dThr, S.nThr);
                        else
                            consistencyRow<0, 2>(x, eV, dx, 4 * j + 1, zs[j], ns[0][j], ns[1][j],
                                                 ns[2][j], idsS[j], K, S.dThr, S.nThr);
                    }
                    if (cr)
                        weightsRow<true>(x, eV, K);
                    else
                        weightsRow<false>(x, eV, K);
                    // One output plane. Planes that are not fed contribute wt * 0 (colour,
                    // moments): the output is 0 * (1 / sumW) = 0 wherever the kernel's result
                    // is kept.
                    auto plane = [&](const float* p, float* const* sanRows, float* out, auto kind) {
                        if (!p) {
                            std::fill(out + x, out + e, 0.f);
                            return;
                        }
                        constexpr Sanitize k = decltype(kind)::value;
                        for (int j = (k == Sanitize::Radiance && cr ? 0 : 1);
                             j <= (k == Sanitize::Radiance && cr ? 3 : 2); ++j)
                            sanitizeSegment<k>(c0, c1, w, p + o[j], sanRows[j]);
                        bilinearPlaneRow<k == Sanitize::Length>(x, eV, dx, sanRows[1], sanRows[2],
                                                                K, out);
                    };
                    using Rad = std::integral_constant<Sanitize, Sanitize::Radiance>;
                    using Mo1 = std::integral_constant<Sanitize, Sanitize::Moment1>;
                    using Mo2 = std::integral_constant<Sanitize, Sanitize::Moment2>;
                    using Len = std::integral_constant<Sanitize, Sanitize::Length>;
                    if (outC)
                        for (int c = 0; c < 3; ++c) {
                            plane(S.pc[c], cs[c], oc[c], Rad{});
                            if (cr && S.pc[c]) catmullRomPlaneRow(x, eV, dx, cs[c], K, oc[c]);
                        }
                    if (outM) {
                        plane(S.pm[0], ms[0], om[0], Mo1{});
                        plane(S.pm[1], ms[1], om[1], Mo2{});
                    }
                    if (outH) {
                        if (S.ph) {
                            plane(S.ph, hs, oh, Len{});
                        } else {
                            // Without prevHistoryLength every tap adds wt * 1 = wt: the sum is
                            // sumW's, term by term.
                            for (int i = x; i < eV; ++i) oh[i] = rSumW[i] * rInv[i];
                        }
                    }
                }
                x = e;
            }
            // Everything else, and the kernel's 3x3-fallback pixels, per pixel.
#pragma GCC ivdep
            for (int x = 0; x < w; ++x) redo[x] = (rFast[x] == 0) | (rSumW[x] < 1e-4f);
            for (int x = nextFlag(redo, 0, w); x < w; x = nextFlag(redo, x + 1, w)) {
                const PixelRef P{rPpx[x], rPpy[x],  rZRef[x], rn0[x],    rn1[x],
                                 rn2[x],  rInvZ[x], rInvN[x], rRefId[x], rOk[x] != 0};
                const PixelOut o = reprojectPixel(S, P);
                for (int c = 0; c < 3; ++c) oc[c][x] = o.c[c];
                for (int c = 0; c < 2; ++c) om[c][x] = o.m[c];
                oh[x] = o.h;
            }
        }
    });
}
