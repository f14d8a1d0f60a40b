// Per-target part of the A-Trous fast path, included by ATrousKernels.cpp once per SIMD target
// (Highway's -inl.h convention): the planes a band works on, and its preparation before the
// filter kernel runs (sanitised copies or the inputs in place, luminance, depth gradient and
// the luminance weight's prefiltered variance).

// Per-target include guard: toggled by foreach_target.h for each target.
#if defined(KESTREL_ATROUS_BANDS_INL_H_) == defined(HWY_TARGET_TOGGLE)
#ifdef KESTREL_ATROUS_BANDS_INL_H_
#undef KESTREL_ATROUS_BANDS_INL_H_
#else
#define KESTREL_ATROUS_BANDS_INL_H_
#endif

#include <hwy/highway.h>
#include <kestrel/PixelMath.h>
#include <kestrel/SimdMath.h>

#include <algorithm>
#include <cstdint>

#include "ATrousKernels.h"

HWY_BEFORE_NAMESPACE();
namespace kestrel::HWY_NAMESPACE {
namespace {

namespace hn = hwy::HWY_NAMESPACE;
constexpr float kEpsL = 1e-10f;        // SVGF eq. 5 epsilon (Falcor uses 1e-10 too)
constexpr float kMaxVariance = 1e32f;  // sanitizePositive's limit for the variance input

// The planes a band computes first: reading its inputs in place, it needs scratch only for them.
// L, INVL, R, G, B and VAR are per signal (a fused pair filters two, executeFused); the
// geometry is shared.
enum Plane {
    GX,
    GY,
    L,
    INVL,
    L2,
    INVL2,
    R,
    G,
    B,
    Z,
    NX,
    NY,
    NZ,
    VAR,
    ID,
    R2,
    G2,
    B2,
    VAR2,
    kPlaneCount
};
constexpr int kComputedPlanes[3] = {0, INVL + 1, INVL2 + 1};  // by signal count
constexpr int kLum[2] = {L, L2}, kInvL[2] = {INVL, INVL2}, kVarPlane[2] = {VAR, VAR2};
constexpr int kRgb[2][3] = {{R, G, B}, {R2, G2, B2}};

template <class Fn>
void copySanitized(const float* __restrict src, float* __restrict dst, int n, Fn fn) {
    for (int x = 0; x < n; ++x) dst[x] = fn(src[x]);
}

void lumaRow(const float* __restrict r, const float* __restrict g, const float* __restrict b,
             float* __restrict l, int n) {
    for (int x = 0; x < n; ++x) l[x] = px::luminance(r[x], g[x], b[x]);
}

/// Depth derivatives of one row (px::minAbsDiff), border columns/rows one-sided.
void gradientRow(const float* __restrict z, const float* __restrict za, const float* __restrict zb,
                 float* __restrict gx, float* __restrict gy, int n, bool up, bool down) {
    for (int x = 0; x < n; ++x) gy[x] = px::minAbsDiff(za[x], z[x], zb[x], up, down);
    if (n < 2) {
        if (n == 1) gx[0] = 0.f;
        return;
    }
    gx[0] = z[1] - z[0];
    for (int x = 1; x + 1 < n; ++x) {
        const float b = z[x] - z[x - 1], f = z[x + 1] - z[x];
        gx[x] = std::fabs(b) <= std::fabs(f) ? b : f;
    }
    gx[n - 1] = z[n - 1] - z[n - 2];
}

void verticalRow(const float* __restrict a, const float* __restrict c, const float* __restrict b,
                 float wa, float wb, float norm, float* __restrict out, int n) {
    for (int x = 0; x < n; ++x) out[x] = (wa * a[x] + 0.5f * c[x] + wb * b[x]) * norm;
}

/// Horizontal (1/4, 1/2, 1/4) of the vertically filtered variance, then the luminance weight's
/// per-pixel factor 1 / (sigma_l sqrt(g3x3(Var)) + eps) (SVGF eq. 5).
void horizontalInvL(const float* __restrict v, float* __restrict invL, int n, float sigmaL) {
    auto finish = [&](float g) { return 1.f / (sigmaL * std::sqrt(std::max(0.f, g)) + kEpsL); };
    if (n == 1) {
        invL[0] = finish(v[0]);
        return;
    }
    invL[0] = finish((0.5f * v[0] + 0.25f * v[1]) / 0.75f);
    // Explicit vectors: GCC leaves this loop scalar (sqrt and division one lane at a time took
    // a fifth of the preparation's time).
    const simd::DF d;
    const int lanes = int(hn::Lanes(d));
    const auto quarter = hn::Set(d, 0.25f), half = hn::Set(d, 0.5f), one = hn::Set(d, 1.f);
    const auto sl = hn::Set(d, sigmaL), eps = hn::Set(d, kEpsL);
    int x = 1;
    for (; x + lanes < n; x += lanes) {
        const auto g = hn::MulAdd(
            quarter, hn::LoadU(d, v + x - 1),
            hn::MulAdd(half, hn::LoadU(d, v + x), hn::Mul(quarter, hn::LoadU(d, v + x + 1))));
        const auto den = hn::MulAdd(sl, hn::Sqrt(hn::Max(g, hn::Zero(d))), eps);
        hn::StoreU(hn::Div(one, den), d, invL + x);
    }
    for (; x + 1 < n; ++x) invL[x] = finish(0.25f * v[x - 1] + 0.5f * v[x] + 0.25f * v[x + 1]);
    invL[n - 1] = finish((0.5f * v[n - 1] + 0.25f * v[n - 2]) / 0.75f);
}

using simd::DF;
using simd::DI;
using simd::VF;
using simd::VI;

/// Where masked loads cannot fault, edge vectors load with a mask of the lanes inside the row,
/// so the planes need no margins and the filter can read its inputs in place.
constexpr bool kMaskedEdges = simd::kMaskedLoadsCannotFault;

/// What every band of one filterFast call shares. The image is filtered in bands of rows, each
/// with private scratch planes covering the band and the rows its taps reach (2 step above and
/// below): scratch then scales with the band, not the frame (at 1080p and step 16, 13 planes of
/// 128 rows, ~13 MB per thread, and 4 planes when the band reads its inputs in place, instead
/// of ~108 MB), at the cost of recomputing the halo rows' terms. Every value depends only on its
/// pixel's neighbourhood, so results do not depend on the banding. Copied bands' rows are
/// `pitch` apart, each followed by a margin of the reach plus one vector (which is also the next
/// row's left margin; the first row has one before it), zeroed where the edge vectors' loads
/// are not masked (!kMaskedEdges), so that they may read past a row's ends.
struct Job {
    Job(FrameContext& ctx, const ATrousBindings* const* bindings, int signalCount,
        const ATrousPass::Settings* signalSettings)
        : b(bindings),
          signals(signalCount),
          settings(signalSettings),
          s(signalSettings[0]),
          width(ctx.extent.width),
          height(ctx.extent.height),
          reach(2 * s.step),
          // Bands of 64 rows (twice the reach from step 16 on): the halo is then a quarter of
          // the band at step 4 (it was half with 32-row bands: 57-62 against 66-70 ms, 1
          // thread), and the largest scratch, step 16's 64 + 2 x 32 rows, stays the same.
          band(std::min(height, std::max(64, 2 * reach))),
          bands((height + band - 1) / band),
          margin(size_t(reach) + hn::Lanes(DF())),
          pitch(size_t(width) + margin),
          bandPixels(margin + size_t(std::min(height, band + 2 * reach)) * pitch),
          depth(b[0]->depth),
          normal(b[0]->normal),
          ids(b[0]->ids),
          withVar(std::any_of(b, b + signals, [](const ATrousBindings* g) { return g->outVar; })),
          checkVar(b[0]->var != nullptr),
          useNormal(s.sigmaN > 0.f) {}
    const ATrousBindings* const* b;
    int signals;
    const ATrousPass::Settings* settings;  ///< per signal (sigmaL, sigmaColor)
    ATrousPass::Settings s;                ///< the first's: the geometric settings
    int width, height, reach, band, bands;
    size_t margin, pitch, bandPixels;
    const ImageView &depth, &normal;
    const int32_t* ids;
    bool withVar, checkVar, useNormal;
};

/// One band's planes: rows [y0, y1) filtered, [base, p1) read (the taps' reach), plane rows
/// `pitch` apart from row `base` on.
struct Band {
    int y0, y1, base, p1;
    size_t pitch;
    float* P[kPlaneCount];
    const int32_t* ids;
    size_t off(int y) const { return size_t(y - base) * pitch; }
};

/// In place: the input planes from row `base` on, rows `width` apart; only the luminance is
/// computed into scratch.
void bindInPlace(const Job& job, Band& band) {
    for (int c = 0; c < 3; ++c) band.P[NX + c] = job.normal.row(c, band.base);
    band.P[Z] = job.depth.row(0, band.base);
    if (job.ids) band.ids = job.ids + size_t(band.base) * size_t(job.width);
    for (int g = 0; g < job.signals; ++g) {
        const int* rgb = kRgb[g];
        float* const* P = band.P;
        for (int c = 0; c < 3; ++c) band.P[rgb[c]] = job.b[g]->color.row(c, band.base);
        if (job.checkVar) band.P[kVarPlane[g]] = job.b[g]->var->row(0, band.base);
        for (int y = band.base; y < band.p1; ++y) {
            const size_t o = band.off(y);
            lumaRow(P[rgb[0]] + o, P[rgb[1]] + o, P[rgb[2]] + o, P[kLum[g]] + o, job.width);
        }
    }
}

/// Copied planes: the margins zeroed (finite: a tap outside the row has weight 0, which
/// multiplies them), then pass 1: sanitised copies and luminance (inputs may hold NaN/Inf;
/// nothing below may). One plane per loop: two streams each, so every loop vectorises.
void copySanitised(const Job& job, const Band& band) {
    const int width = job.width;
    const size_t margin = job.margin;
    float* const* P = band.P;
    for (int k = 0; k < kPlaneCount && !kMaskedEdges; ++k) {
        if (!P[k]) continue;  // a plane this signal count does not use
        std::fill_n(P[k] - margin, margin, 0.f);
        for (int y = band.base; y < band.p1; ++y)
            std::fill_n(P[k] + band.off(y) + width, margin, 0.f);
    }
    for (int y = band.base; y < band.p1; ++y) {
        const size_t o = band.off(y);
        for (int c = 0; c < 3; ++c)
            copySanitized(job.normal.row(c, y), P[NX + c] + o, width, px::sanitizeNormal);
        copySanitized(job.depth.row(0, y), P[Z] + o, width, px::sanitizeDepth);
        if (job.ids)
            std::copy_n(job.ids + size_t(y) * size_t(width), width,
                        reinterpret_cast<int32_t*>(P[ID]) + o);
        for (int g = 0; g < job.signals; ++g) {
            const int* rgb = kRgb[g];
            for (int c = 0; c < 3; ++c)
                copySanitized(job.b[g]->color.row(c, y), P[rgb[c]] + o, width,
                              [](float v) { return px::sanitize(v); });
            if (job.checkVar)
                copySanitized(job.b[g]->var->row(0, y), P[kVarPlane[g]] + o, width,
                              [](float v) { return px::sanitizePositive(v, kMaxVariance); });
            lumaRow(P[rgb[0]] + o, P[rgb[1]] + o, P[rgb[2]] + o, P[kLum[g]] + o, width);
        }
    }
}

/// Pass 2: depth gradient (edge-preserving one-sided differences) and the luminance weight's
/// 1 / (sigma_l sqrt(g3x3(Var)) + eps) with a 3x3 Gaussian prefilter (SVGF section 4.4),
/// renormalised at the image border. Both weigh only the centre pixel p, never a tap q, so only
/// the band's own rows need them, not its halo (the 3x3 terms read one row beyond them: inside
/// the reach). vcol: a row of scratch.
void centreTerms(const Job& job, const Band& band, float* vcol) {
    const int width = job.width;
    const size_t bandPitch = band.pitch;
    float* const* P = band.P;
    for (int y = band.y0; y < band.y1; ++y) {
        const size_t o = band.off(y);
        const bool up = y > 0, down = y + 1 < job.height;
        const float* z = P[Z] + o;
        gradientRow(z, up ? z - bandPitch : z, down ? z + bandPitch : z, P[GX] + o, P[GY] + o,
                    width, up, down);
        for (int g = 0; g < job.signals; ++g) {
            float* invL = P[kInvL[g]] + o;
            if (!job.checkVar) {
                std::fill(invL, invL + width, 1.f / (job.settings[g].sigmaColor + kEpsL));
                continue;
            }
            // Separable 3x3 Gaussian (1/4, 1/2, 1/4)^2: vertical, then horizontal; weights of
            // taps outside the image are dropped and the rest renormalised.
            const float* v = P[kVarPlane[g]] + o;
            const float* va = up ? v - bandPitch : v;
            const float* vb = down ? v + bandPitch : v;
            const float wa = up ? 0.25f : 0.f, wb = down ? 0.25f : 0.f;
            const float vNorm = 1.f / (0.5f + wa + wb);
            verticalRow(va, v, vb, wa, wb, vNorm, vcol, width);
            horizontalInvL(vcol, invL, width, job.settings[g].sigmaL);
        }
    }
}

}  // namespace
}  // namespace kestrel::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#endif  // KESTREL_ATROUS_BANDS_INL_H_
