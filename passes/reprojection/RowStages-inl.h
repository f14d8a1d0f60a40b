// The per-pixel stages of a row before the taps, each over the row's named scratch rows: where
// the pixel was last frame (motion vectors, matrices or identity), the integer tap offsets and
// fractions, and the resampling weights.
// Included once per SIMD target by Reproject.cpp (hwy/foreach_target.h): the toggled guard.
#if defined(KESTREL_REPROJECTION_ROW_STAGES_INL_H_) == defined(HWY_TARGET_TOGGLE)
#ifdef KESTREL_REPROJECTION_ROW_STAGES_INL_H_
#undef KESTREL_REPROJECTION_ROW_STAGES_INL_H_
#else
#define KESTREL_REPROJECTION_ROW_STAGES_INL_H_
#endif

#include <hwy/highway.h>
#include <kestrel/Kestrel.h>
#include <kestrel/PixelMath.h>

#include <cmath>
#include <cstdint>
#include <utility>
#include <vector>

#include "DepthChangeModel.h"
#include "PixelReprojection-inl.h"
#include "TransformTable-inl.h"

HWY_BEFORE_NAMESPACE();
namespace kestrel::HWY_NAMESPACE {
namespace {

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

/// One thread's row scratch, by name: a row's per-pixel terms, w elements each (a cache line of
/// padding apart), indexed by x.
struct Rows {
    float *invZ, *invN;            ///< 1 / (fwidth + 0.01) of depth and normal (Derivatives-inl.h)
    float* n[3];                   ///< this pixel's sanitised normal
    float* zRef;                   ///< the depth a tap's last-frame depth is compared with
    float *ppx, *ppy;              ///< previous-frame position, continuous pixel coordinates
    float *fx, *fy;                ///< its bilinear fractions
    float* sumW;                   ///< the tap kernel's weight sum (below 1e-4: the 3x3 fallback)
    float* sink[6];                ///< where absent outputs go: colour 0-2, moments 3-4, length 5
    float *bw[4], *wx[4], *wy[4];  ///< bilinear and (Catmull-Rom) separable weights
    /// This frame's sanitised depth (plane 0) and normal (1-3), rows y-1..y+1 in a ring of
    /// three slots (row % 3): each element sanitised once, not once per derivative reading it.
    float* geom[3][4];
    int32_t *dx, *dy;  ///< integer tap offsets x0 - x, y0 - y
    int32_t* fast;     ///< the tap kernel can take the pixel (valid, every tap inside the image)
    int32_t* refId;    ///< the pixel's object id (0 without ids)
    int32_t* ok;       ///< the position is usable
    int32_t* zeroIds;  ///< w zeros: refId's source without ids
    uint8_t* redo;     ///< reprojectPixel recomputes the pixel
};

/// The named rows in `sc`, grown for rows of w pixels: float rows, then int rows, each
/// w + kPad elements after the previous.
inline Rows rowsIn(Scratch& sc, int w) {
    constexpr int kF = 41, kI = 6, kPad = 16;
    const size_t ws = size_t(w) + kPad;
    sc.reserve(ws * kF, ws * kI, size_t(w));
    float* f = sc.f.data();
    int32_t* i = sc.i.data();
    auto nextF = [&] { return std::exchange(f, f + ws); };
    auto nextI = [&] { return std::exchange(i, i + ws); };
    Rows r;
    r.invZ = nextF();
    r.invN = nextF();
    for (float*& p : r.n) p = nextF();
    r.zRef = nextF();
    r.ppx = nextF();
    r.ppy = nextF();
    r.fx = nextF();
    r.fy = nextF();
    r.sumW = nextF();
    for (float*& p : r.sink) p = nextF();
    for (float*& p : r.bw) p = nextF();
    for (float*& p : r.wx) p = nextF();
    for (float*& p : r.wy) p = nextF();
    for (auto& slot : r.geom)
        for (float*& p : slot) p = nextF();
    r.dx = nextI();
    r.dy = nextI();
    r.fast = nextI();
    r.refId = nextI();
    r.ok = nextI();
    r.zeroIds = nextI();
    r.redo = sc.b.data();
    return r;
}

// Previous-frame positions of pixels [a, b) of row y from motion vectors; the depth to test
// taps against is the camera model's prediction (the identity model: the depth itself).
HWY_INLINE void positionsFromMotion(const Rows& r, const ImageView& motion,
                                    const DepthChangeModel& depthChange, const float* zRow, int y,
                                    int a, int b) {
    float *rPpx = r.ppx, *rPpy = r.ppy, *rZRef = r.zRef;
    int32_t* rOk = r.ok;
    const float *mx = motion.row(0, y), *my = motion.row(1, y);
    const float fy0 = float(y) + 0.5f, rowTerm = depthChange.rowTerm(y);
#pragma GCC ivdep
    for (int x = a; x < b; ++x) {
        rPpx[x] = (float(x) + 0.5f) + mx[x];
        rPpy[x] = fy0 + my[x];
        const float z = px::sanitizeDepth(zRow[x]);
        rZRef[x] = z < kBackgroundDepth ? depthChange.predict(z, x, rowTerm) : z;
        rOk[x] = 1;
    }
}

// Previous-frame positions of pixels [a, b) of row y from world positions and the per-object
// matrices; ok = 0 where there is no surface position to reproject.
HWY_INLINE void positionsFromMatrices(const Rows& r, const ImageView& position,
                                      const TransformTable& table, const int32_t* curIds,
                                      const float* zRow, int w, int y, int a, int b) {
    float *rPpx = r.ppx, *rPpy = r.ppy, *rZRef = r.zRef;
    int32_t* rOk = r.ok;
    const size_t rowStart = size_t(y) * size_t(w);
    for (int x = a; x < b; ++x) {
        float ppx = float(x) + 0.5f, ppy = float(y) + 0.5f;
        float zRef = px::sanitizeDepth(zRow[x]);
        bool ok = true;
        const int32_t id = curIds ? curIds[rowStart + size_t(x)] : 0;
        if (zRef >= kBackgroundDepth || (curIds && id == kBackgroundId)) {
            ok = false;  // no surface position to reproject
        } else {
            const ObjectTransforms& t = curIds ? table.get(id) : table.fallback();
            Vec3 p{position.at(0, x, y), position.at(1, x, y), position.at(2, x, y)};
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
}

// Without motion or positions: every pixel where it is (a static camera).
HWY_INLINE void positionsIdentity(const Rows& r, const float* zRow, int y, int a, int b) {
    float *rPpx = r.ppx, *rPpy = r.ppy, *rZRef = r.zRef;
    int32_t* rOk = r.ok;
    const float fy0 = float(y) + 0.5f;
#pragma GCC ivdep
    for (int x = a; x < b; ++x) {
        rPpx[x] = float(x) + 0.5f;
        rPpy[x] = fy0;
        rZRef[x] = px::sanitizeDepth(zRow[x]);
        rOk[x] = 1;
    }
}

// Integer tap offsets and bilinear fractions of pixels [a, b) of row y; fast: the tap kernel
// can take the pixel (valid position, taps x0 - lo .. x0 + hi and likewise in y inside the
// w x h image).
HWY_INLINE void tapOffsets(const Rows& r, const int32_t* refIds, int w, int h, int lo, int hi,
                           int y, int a, int b) {
    const float *rPpx = r.ppx, *rPpy = r.ppy;
    float *rFx = r.fx, *rFy = r.fy;
    int32_t *rDx = r.dx, *rDy = r.dy, *rFast = r.fast, *rRefId = r.refId, *rOk = r.ok;
#pragma GCC ivdep
    for (int x = a; x < b; ++x) {
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
}

// Bilinear (and, with cr, Catmull-Rom) weights of pixels [a, b) from their fractions.
HWY_INLINE void tapWeights(const Rows& r, bool cr, int a, int b) {
    const float *rFx = r.fx, *rFy = r.fy;
    float *bw0 = r.bw[0], *bw1 = r.bw[1], *bw2 = r.bw[2], *bw3 = r.bw[3];
#pragma GCC ivdep
    for (int x = a; x < b; ++x) {
        const float fx = rFx[x], fy = rFy[x];
        bw0[x] = (1 - fx) * (1 - fy);
        bw1[x] = fx * (1 - fy);
        bw2[x] = (1 - fx) * fy;
        bw3[x] = fx * fy;
    }
    if (!cr) return;
    float *wx0 = r.wx[0], *wx1 = r.wx[1], *wx2 = r.wx[2], *wx3 = r.wx[3];
    float *wy0 = r.wy[0], *wy1 = r.wy[1], *wy2 = r.wy[2], *wy3 = r.wy[3];
#pragma GCC ivdep
    for (int x = a; x < b; ++x) {
        float cx[4], cy[4];
        catmullRomWeights(rFx[x], cx);
        catmullRomWeights(rFy[x], cy);
        wx0[x] = cx[0];
        wx1[x] = cx[1];
        wx2[x] = cx[2];
        wx3[x] = cx[3];
        wy0[x] = cy[0];
        wy1[x] = cy[1];
        wy2[x] = cy[2];
        wy3[x] = cy[3];
    }
}

}  // namespace
}  // namespace kestrel::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#endif  // toggled include guard
