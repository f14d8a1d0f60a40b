// One frame's reprojection: the frame's inputs and outputs, then each row in tiles through the
// stages (derivatives, positions, tap offsets, weights, the tap kernel) and the per-pixel
// reprojection of what the kernel leaves.
//
// Compiled once per SIMD target (hwy/foreach_target.h re-includes this file, and with it the
// -inl.h files, for each one): the whole frame, scalar loops included (they auto-vectorise for
// the target), lives in kestrel::N_<TARGET>; the HWY_ONCE part at the end picks the running
// CPU's best target.
#include "Reproject.h"

#include <denoise/TapsMask.h>
#include <kestrel/PixelMath.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <optional>

#include "DepthChangeModel.h"

#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "Reproject.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep
// After foreach_target.h: once per target.
#include <hwy/highway.h>

#include "Derivatives-inl.h"
#include "PixelReprojection-inl.h"
#include "RowStages-inl.h"
#include "TapKernel-inl.h"
#include "TransformTable-inl.h"

HWY_BEFORE_NAMESPACE();
namespace kestrel::HWY_NAMESPACE {
namespace {

/// A frame's outputs (null: not wanted).
struct Outputs {
    const ImageView *color = nullptr, *moments = nullptr, *historyLength = nullptr,
                    *resampleBlur = nullptr;
    int32_t* taps = nullptr;
};

/// What every row of a frame reads.
struct Frame {
    Sources S;
    Outputs out;
    const ImageView *depth = nullptr, *normal = nullptr, *motion = nullptr, *position = nullptr;
    const int32_t* curIds = nullptr;  ///< this frame's ids (the matrix path's transforms)
    const int32_t* ids = nullptr;     ///< this frame's ids where last frame's are given too (tests)
    std::optional<TransformTable> table;  ///< the matrix path's
    DepthChangeModel depthChange;
    bool geometry = false;  ///< the depth and normal tests run
    int lo = 0, hi = 0;     ///< the tap kernel's footprint around (x0, y0): x0 - lo .. x0 + hi
    float depthPrecision = 0.f;
};

// Index of the first nonzero flag in [from, end), or end (memchr scans 32 bytes at a time).
inline int nextFlag(const uint8_t* flags, int from, int end) {
    if (from >= end) return end;
    const void* p = std::memchr(flags + from, 1, size_t(end - from));
    return p ? int(static_cast<const uint8_t*>(p) - flags) : end;
}
thread_local Scratch tScratch;

// This frame's depth (and, with the tests, normal) of row `row`, sanitised into its ring slot.
HWY_INLINE void sanitizeGeometryRow(const Frame& F, const Rows& r, int w, int row) {
    float* const* slot = r.geom[row % 3];
    const float* z = F.depth->row(0, row);
    float* zo = slot[0];
    for (int x = 0; x < w; ++x) zo[x] = px::sanitizeDepth(z[x]);
    if (!F.geometry) return;  // normals serve only the tests
    for (int c = 0; c < 3; ++c) {
        const float* n = F.normal->row(c, row);
        float* no = slot[1 + c];
        for (int x = 0; x < w; ++x) no[x] = px::sanitizeNormal(n[x]);
    }
}

// The sanitised rows the derivatives of row y read (absent neighbour rows alias row y).
HWY_INLINE GeomRows geomRowsAt(const Rows& r, int y, bool u, bool d, float depthStep) {
    const int yu = u ? y - 1 : y, yd = d ? y + 1 : y;  // absent neighbours are not used
    GeomRows g;
    g.depthStep = depthStep;
    for (int j = 0; j < 3; ++j) {
        const int yy = j == 0 ? y : j == 1 ? yu : yd;
        g.z[j] = r.geom[yy % 3][0];
        for (int c = 0; c < 3; ++c) g.n[c][j] = r.geom[yy % 3][1 + c];
    }
    return g;
}

// Row y's terms for the tap kernel and its output rows (absent outputs: scratch sinks).
HWY_INLINE RowTerms rowTermsAt(const Frame& F, const Rows& r, int y, size_t rowStart) {
    const Outputs& o = F.out;
    float *oc[3], *om[2], *oh;
    for (int c = 0; c < 3; ++c) oc[c] = o.color ? o.color->row(c, y) : r.sink[c];
    for (int c = 0; c < 2; ++c) om[c] = o.moments ? o.moments->row(c, y) : r.sink[3 + c];
    oh = o.historyLength ? o.historyLength->row(0, y) : r.sink[5];
    return RowTerms{r.zRef,
                    r.n[0],
                    r.n[1],
                    r.n[2],
                    r.invZ,
                    r.invN,
                    {r.bw[0], r.bw[1], r.bw[2], r.bw[3]},
                    {r.wx[0], r.wx[1], r.wx[2], r.wx[3]},
                    {r.wy[0], r.wy[1], r.wy[2], r.wy[3]},
                    r.refId,
                    r.sumW,
                    {oc[0], oc[1], oc[2]},
                    {om[0], om[1]},
                    oh,
                    o.color != nullptr,
                    o.moments != nullptr,
                    o.historyLength != nullptr,
                    o.taps ? o.taps + rowStart : nullptr,
                    F.S.shared ? F.S.shared + rowStart : nullptr};
}

// The tap kernel over pixels [a, b) of row y (vectors: the row is at least a vector wide and
// the target has FMA); without it no pixel is fast.
HWY_INLINE void tapKernel(const Frame& F, const RowTerms& R, const Rows& r, bool vectors, int y,
                          int a, int b) {
    const Sources& S = F.S;
    const bool cr = S.catmullRom;
    int32_t *rFast = r.fast, *rDx = r.dx, *rDy = r.dy;
    if (!vectors)
        std::fill(rFast + a, rFast + b, 0);
    else if (S.shared)
        cr ? tapRow<true, false, TapMode::Shared>(S, R, y, a, b, rFast, rDx, rDy)
           : tapRow<false, false, TapMode::Shared>(S, R, y, a, b, rFast, rDx, rDy);
    else if (R.taps)
        tapRows<TapMode::Record>(S, R, y, a, b, rFast, rDx, rDy, cr, F.geometry);
    else
        tapRows<TapMode::Test>(S, R, y, a, b, rFast, rDx, rDy, cr, F.geometry);
}

// Every stage before the per-pixel pass over pixels [a, b) of row y.
HWY_INLINE void reprojectTile(const Frame& F, const Rows& r, const RowTerms& R, const GeomRows& g,
                              const int32_t* refIds, bool vectors, int y, int a, int b) {
    const int w = F.S.w, h = F.S.h;
    const float* zRow = r.geom[y % 3][0];  // sanitised (sanitizeDepth is idempotent)
    if (F.geometry) {
        rowDerivatives(g, y > 0, y + 1 < h, w, a, b, r.invZ, r.invN, r.n[0], r.n[1], r.n[2]);
    } else {  // reprojectPixel's tests then compare 0 with infinite thresholds
        for (float* p : {r.invZ, r.invN, r.n[0], r.n[1], r.n[2]}) std::fill(p + a, p + b, 0.f);
    }
    if (F.motion)
        positionsFromMotion(r, *F.motion, F.depthChange, zRow, y, a, b);
    else if (F.table)
        positionsFromMatrices(r, *F.position, *F.table, F.curIds, zRow, w, y, a, b);
    else
        positionsIdentity(r, zRow, y, a, b);
    tapOffsets(r, refIds, w, h, F.lo, F.hi, y, a, b);
    tapWeights(r, F.S.catmullRom, a, b);
    tapKernel(F, R, r, vectors, y, a, b);
}

// The pixels of row y the tap kernel did not take or left to the 3x3 fallback, by
// reprojectPixel, and resampleBlur of the whole row.
HWY_INLINE void perPixelRow(const Frame& F, const Rows& r, const RowTerms& R, int y,
                            size_t rowStart) {
    const int w = F.S.w;
    uint8_t* redo = r.redo;
    const int32_t* rFast = r.fast;
    const float *rSumW = r.sumW, *rFx = r.fx, *rFy = r.fy;
#pragma GCC ivdep
    for (int x = 0; x < w; ++x) redo[x] = (rFast[x] == 0) | (rSumW[x] < 1e-4f);
    // resampleBlur where the tap kernel's result is kept (its weight sum is at least 1e-4
    // there: not disoccluded) from the fractions; reprojectPixel's elsewhere.
    float* ob = F.out.resampleBlur ? F.out.resampleBlur->row(0, y) : nullptr;
    if (ob)
        for (int x = 0; x < w; ++x) ob[x] = redo[x] ? 0.f : resampleBlur(rFx[x], rFy[x]);
    int32_t* outTaps = F.out.taps;
    const int32_t* shared = F.S.shared;
    for (int x = nextFlag(redo, 0, w); x < w; x = nextFlag(redo, x + 1, w)) {
        const PixelRef P{r.ppx[x],
                         r.ppy[x],
                         r.zRef[x],
                         r.n[0][x],
                         r.n[1][x],
                         r.n[2][x],
                         r.invZ[x],
                         r.invN[x],
                         r.refId[x],
                         r.ok[x] != 0,
                         shared ? shared[rowStart + size_t(x)] : 0};
        const PixelOut o = reprojectPixel(F.S, P);
        if (outTaps) outTaps[rowStart + size_t(x)] = o.taps;
        for (int c = 0; c < 3; ++c) R.oc[c][x] = o.c[c];
        for (int c = 0; c < 2; ++c) R.om[c][x] = o.m[c];
        R.oh[x] = o.h;
        if (ob) ob[x] = o.blur;
    }
}

// Rows [ya, yb) on this thread.
void reprojectRows(const Frame& F, int ya, int yb) {
    // Local copies: int stores to the scratch rows could otherwise alias the frame's extent.
    const int w = F.S.w, h = F.S.h;
    constexpr int kTile = 256;
    const Rows r = rowsIn(tScratch, w);
    if (ya > 0) sanitizeGeometryRow(F, r, w, ya - 1);
    sanitizeGeometryRow(F, r, w, ya);
    std::fill(r.zeroIds, r.zeroIds + w, 0);
    // Rows narrower than a vector are left to reprojectPixel (all rows without FMA).
    const bool vectors = kTapKernel && w >= int(hn::Lanes(DF()));
    for (int y = ya; y < yb; ++y) {
        const bool u = y > 0, d = y + 1 < h;
        if (d) sanitizeGeometryRow(F, r, w, y + 1);
        const GeomRows g = geomRowsAt(r, y, u, d, F.depthPrecision);
        const size_t rowStart = size_t(y) * size_t(w);
        const int32_t* refIds = F.ids ? F.ids + rowStart : r.zeroIds;
        const RowTerms R = rowTermsAt(F, r, y, rowStart);
        // The row in tiles of kTile pixels (the last one takes the remainder): each stage's
        // slice of the row scratch then stays in the L1 cache from one stage to the next.
        for (int a = 0, b = 0; a < w; a = b) {
            b = w - a < 2 * kTile ? w : a + kTile;
            reprojectTile(F, r, R, g, refIds, vectors, y, a, b);
        }
        // Everything else, and the kernel's 3x3-fallback pixels, per pixel.
        perPixelRow(F, r, R, y, rowStart);
    }
}

/// The outputs the graph wants; with sharedTaps, `taps` is a copy of it (resolve leaves taps
/// out then, but a harness may still ask for it).
Outputs outputsOf(PassIO& io, const ReprojectionPass::Declaration& dc, size_t pixels) {
    Outputs o;
    o.color = io.has(dc.color) ? &io.output(dc.color) : nullptr;
    o.moments = io.has(dc.moments) ? &io.output(dc.moments) : nullptr;
    o.historyLength = io.has(dc.historyLength) ? &io.output(dc.historyLength) : nullptr;
    o.resampleBlur = io.has(dc.resampleBlur) ? &io.output(dc.resampleBlur) : nullptr;
    o.taps = io.has(dc.taps) ? io.output(dc.taps).ints() : nullptr;
    const int32_t* shared = io.has(dc.sharedTaps) ? io.input(dc.sharedTaps).ints() : nullptr;
    if (shared && o.taps) {
        std::copy_n(shared, pixels, o.taps);
        o.taps = nullptr;
    }
    return o;
}

void zeroOutputs(const Outputs& out, size_t pixels) {
    for (const ImageView* o : {out.color, out.moments, out.historyLength, out.resampleBlur})
        if (o)
            for (int c = 0; c < o->channels(); ++c)
                std::fill(o->channel(c), o->channel(c) + o->pixels(), 0.f);
    if (out.taps) std::fill(out.taps, out.taps + pixels, 0);
}

/// Every plane the taps read, and the consistency test's parameters.
Sources sourcesOf(PassIO& io, const ReprojectionPass::Declaration& dc,
                  const ReprojectionPass::Settings& settings, int w, int h) {
    Sources S;
    S.w = w;
    S.h = h;
    S.pz = io.input(dc.prevDepth).channel(0);
    for (int c = 0; c < 3; ++c) S.pn[c] = io.input(dc.prevNormal).channel(c);
    const bool useIds = io.has(dc.objectId) && io.has(dc.prevObjectId);
    S.pIds = useIds ? io.input(dc.prevObjectId).ints() : nullptr;
    const bool colorValid = io.has(dc.prevColor);
    if (colorValid)
        for (int c = 0; c < 3; ++c) S.pc[c] = io.input(dc.prevColor).channel(c);
    if (io.has(dc.prevMoments))
        for (int c = 0; c < 2; ++c) S.pm[c] = io.input(dc.prevMoments).channel(c);
    if (io.has(dc.prevHistoryLength)) S.ph = io.input(dc.prevHistoryLength).channel(0);
    S.dThr = settings.depthThreshold;
    S.nThr2 = settings.normalThreshold * settings.normalThreshold;
    S.catmullRom = settings.catmullRom && colorValid;
    S.shared = io.has(dc.sharedTaps) ? io.input(dc.sharedTaps).ints() : nullptr;
    // A pixel whose motion was moved after its taps were tested (VirtualMotion): this frame's
    // taps are tested here (the shared ones are the same tests' outcomes everywhere else).
    if (S.shared && std::find(S.shared, S.shared + size_t(w) * size_t(h), taps::kUntested) !=
                        S.shared + size_t(w) * size_t(h))
        S.shared = nullptr;
    return S;
}

/// The pass for this target.
void reproject(FrameContext& ctx, PassIO& io, const ReprojectionPass::Settings& settings) {
    const ReprojectionPass::Declaration& dc = ReprojectionPass::declaration();
    const int w = ctx.extent.width, h = ctx.extent.height;
    const size_t pixels = size_t(w) * size_t(h);
    Frame F;
    F.out = outputsOf(io, dc, pixels);
    // Without last frame's geometry no tap can be tested; without any history there is nothing
    // to reproject: all outputs 0, history length 0.
    if (!io.has(dc.prevDepth) || !io.has(dc.prevNormal) ||
        (!io.has(dc.prevColor) && !io.has(dc.prevMoments))) {
        zeroOutputs(F.out, pixels);
        return;
    }
    F.S = sourcesOf(io, dc, settings, w, h);
    F.depth = &io.input(dc.depth);
    F.normal = &io.input(dc.normal);
    F.curIds = io.has(dc.objectId) ? io.input(dc.objectId).ints() : nullptr;
    F.ids = io.has(dc.objectId) && io.has(dc.prevObjectId) ? F.curIds : nullptr;
    F.motion = io.has(dc.motion) ? &io.input(dc.motion) : nullptr;
    F.position = io.has(dc.position) ? &io.input(dc.position) : nullptr;
    if (!F.motion && F.position && ctx.scene && ctx.previousScene && ctx.scene->hasCamera &&
        ctx.previousScene->hasCamera)
        F.table.emplace(*ctx.scene, *ctx.previousScene);
    // Infinite thresholds (geometryTests off): no tap can fail the depth or normal test, so
    // neither the derivatives nor the tests are computed; with sharedTaps no test is.
    F.geometry = !F.S.shared && (std::isfinite(F.S.dThr) || std::isfinite(F.S.nThr2));
    // Tap margin of the tap kernel around (x0, y0): Catmull-Rom reads x0-1..x0+2.
    F.lo = F.S.catmullRom ? 1 : 0;
    F.hi = F.S.catmullRom ? 2 : 1;
    F.depthPrecision = settings.depthPrecision;
    // With motion vectors only, the depth a static surface had last frame comes from a camera
    // model fitted to this frame's correspondences (DepthChangeModel.h); the identity otherwise.
    if (F.motion && settings.cameraDepth && F.geometry && std::isfinite(F.S.dThr))
        F.depthChange =
            fitDepthChange({w, h, F.depth->channel(0), F.motion->channel(0), F.motion->channel(1),
                            F.ids, F.S.pz, F.S.pIds, F.S.dThr, settings.depthPrecision});
    ctx.parallelRows(h, [&](int ya, int yb) { reprojectRows(F, ya, yb); });
}

}  // namespace
}  // namespace kestrel::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace kestrel {
namespace {
HWY_EXPORT(reproject);
}  // namespace

void reprojectFrame(FrameContext& ctx, PassIO& io, const ReprojectionPass::Settings& settings) {
    HWY_DYNAMIC_DISPATCH(reproject)(ctx, io, settings);
}
}  // namespace kestrel
#endif  // HWY_ONCE
