// Compiled once per SIMD target (hwy/foreach_target.h re-includes this file for each one):
// the scalar loops auto-vectorise for each instruction set (and std::fma becomes one
// instruction where there is FMA); the HWY_ONCE part at the end picks the running CPU's
// best target.
#include "ClampedAccumulationPass.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "ClampedAccumulationPass.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep
#include <hwy/highway.h>

HWY_BEFORE_NAMESPACE();
namespace kestrel::passes::HWY_NAMESPACE {
namespace {

// Inputs are clamped to this magnitude: squares of 49+ window samples then stay finite.
constexpr float kMaxValue = 1e18f;

inline float sanitise(float v) {
    return v == v ? std::clamp(v, -kMaxValue, kMaxValue) : 0.f;
}

// Floating-point evaluation. The plugin is compiled with -ffp-contract=off and every fused
// multiply-add is spelled out with std::fma: the arithmetic is exactly the one the compiler
// generated for the previous implementation, so results are bit-identical to it, and they no
// longer depend on what a compiler version chooses to contract.

struct Params {
    float alpha, k;
    bool holdCurrent;  ///< widen the box to contain the current colour
};

// One channel of one pixel from its window sums s1 = sum(C_q - C_p), s2 = sum((C_q - C_p)^2)
// over n samples (inv = 1 / n) and its raw history value hv (finite where valid).
inline float blend(Params p, float centre, float s1, float s2, float inv, float hv) {
    const float m1 = s1 * inv;
    const float var = std::max(0.f, std::fma(s2, inv, -(m1 * m1)));
    const float mu = centre + m1, sigma = std::sqrt(var);
    float lo = std::fma(-p.k, sigma, mu), hi = std::fma(p.k, sigma, mu);
    // A window that straddles an edge (or a lone bright pixel) can have a box that excludes the
    // centre's own colour: the history would be pulled towards the neighbours even where it
    // equals the current colour (a black background beside a lit wall grows a halo).
    lo = p.holdCurrent ? std::min(lo, centre) : lo;
    hi = p.holdCurrent ? std::max(hi, centre) : hi;
    const float clamped = std::clamp(hv, lo, hi);
    return std::fma(p.alpha, centre, (1.f - p.alpha) * clamped);
}

inline bool validHistory(const float* len, const float* h0, const float* h1, const float* h2,
                         int x) {
    return (!len || len[x] > 0.f) && std::isfinite(h0[x]) && std::isfinite(h1[x]) &&
           std::isfinite(h2[x]);
}

/// Rows of one output row: the sanitised colour of window rows ya..yb, and this row's planes.
struct RowIo {
    const float* const* win[3];       ///< win[c][i]: sanitised channel c of row ya + i
    int rows;                         ///< yb - ya + 1
    int centre;                       ///< index of row y in win
    const float *h0, *h1, *h2, *len;  ///< history, history length (null when not fed)
    const float* lenOrOne;            ///< the history length, or a row of ones
    float *o0, *o1, *o2;
};

// Pixel x with the window clipped to the image: the samples that exist, in window order (row
// by row, left to right). Clipped samples are left out; the previous implementation added
// them as (0 - C_p) * 0 = +-0, which changes neither sum.
void edgePixel(const Params& p, int w, int r, int x, const RowIo& io) {
    float* out[3] = {io.o0, io.o1, io.o2};
    const bool valid = validHistory(io.len, io.h0, io.h1, io.h2, x);
    const float* hist[3] = {io.h0, io.h1, io.h2};
    const int xa = std::max(0, x - r), xb = std::min(w - 1, x + r);
    const float inv = 1.f / float(io.rows * (xb - xa + 1));
    for (int c = 0; c < 3; ++c) {
        const float centre = io.win[c][io.centre][x];
        if (!valid) {
            out[c][x] = centre;
            continue;
        }
        float s1 = 0, s2 = 0;
        for (int i = 0; i < io.rows; ++i)
            for (int xx = xa; xx <= xb; ++xx) {
                const float d = io.win[c][i][xx] - centre;
                s1 += d;
                s2 = std::fma(d, d, s2);
            }
        out[c][x] = blend(p, centre, s1, s2, inv, hist[c][x]);
    }
}

// kLanes pixels x0 .. x0 + kLanes - 1 whose whole window lies inside the row: the sums are
// kept in registers, the window visited in order, and every lane loop vectorises.
constexpr int kLanes = 16;

void interiorBlock(const Params& p, int r, int x0, const RowIo& io) {
    float s1[3][kLanes] = {}, s2[3][kLanes] = {}, cen[3][kLanes];
    for (int c = 0; c < 3; ++c)
        for (int l = 0; l < kLanes; ++l) cen[c][l] = io.win[c][io.centre][x0 + l];
    for (int i = 0; i < io.rows; ++i) {
        const float *q0 = io.win[0][i] + x0, *q1 = io.win[1][i] + x0, *q2 = io.win[2][i] + x0;
        for (int dx = -r; dx <= r; ++dx)
            for (int l = 0; l < kLanes; ++l) {
                const float d0 = q0[dx + l] - cen[0][l], d1 = q1[dx + l] - cen[1][l],
                            d2 = q2[dx + l] - cen[2][l];
                s1[0][l] += d0;
                s2[0][l] = std::fma(d0, d0, s2[0][l]);
                s1[1][l] += d1;
                s2[1][l] = std::fma(d1, d1, s2[1][l]);
                s1[2][l] += d2;
                s2[2][l] = std::fma(d2, d2, s2[2][l]);
            }
    }
    const float inv = 1.f / float(io.rows * (2 * r + 1));
    // Unconditional loads (io.lenOrOne: the history length, or a row of ones when it is not
    // fed), selects: the lane loop vectorises.
    const float *h0 = io.h0 + x0, *h1 = io.h1 + x0, *h2 = io.h2 + x0, *ln = io.lenOrOne + x0;
    float *o0 = io.o0 + x0, *o1 = io.o1 + x0, *o2 = io.o2 + x0;
    const Params q = p;
    constexpr float kFinite = std::numeric_limits<float>::max();
#pragma GCC ivdep
    for (int l = 0; l < kLanes; ++l) {
        const bool valid = (ln[l] > 0.f) & (std::fabs(h0[l]) <= kFinite) &
                           (std::fabs(h1[l]) <= kFinite) & (std::fabs(h2[l]) <= kFinite);
        const float b0 = blend(q, cen[0][l], s1[0][l], s2[0][l], inv, h0[l]);
        const float b1 = blend(q, cen[1][l], s1[1][l], s2[1][l], inv, h1[l]);
        const float b2 = blend(q, cen[2][l], s1[2][l], s2[2][l], inv, h2[l]);
        o0[l] = valid ? b0 : cen[0][l];
        o1[l] = valid ? b1 : cen[1][l];
        o2[l] = valid ? b2 : cen[2][l];
    }
}

// Per-thread scratch: a ring of 2 radius + 1 sanitised rows per channel.
thread_local std::vector<float> tRing;

/// The pass for this target (its parameters as arguments).
void executeOnTarget(FrameContext& ctx, PassIO& io, float alpha_, float k_, int radius_,
                     bool holdCurrent_) {
    const ClampedAccumulationPass::Declaration& d = ClampedAccumulationPass::declaration();
    const ImageView& cur = io.input(d.color);
    const ImageView& out = io.output(d.colorOut);
    const int w = cur.width(), h = cur.height(), r = radius_;
    const bool hasHistory = io.has(d.history);
    const ImageView* hist = hasHistory ? &io.input(d.history) : nullptr;
    const ImageView* len = io.has(d.historyLength) ? &io.input(d.historyLength) : nullptr;

    if (!hasHistory) {  // first frame or no reprojection: alpha = 1 everywhere
        ctx.parallelRows(h, [&](int y0, int y1) {
            for (int c = 0; c < 3; ++c)
                for (int y = y0; y < y1; ++y) {
                    const float* s = cur.row(c, y);
                    float* d = out.row(c, y);
                    for (int x = 0; x < w; ++x) d[x] = sanitise(s[x]);
                }
        });
        return;
    }

    const Params prm{alpha_, k_, holdCurrent_};
    const int ringRows = 2 * r + 1;
    ctx.parallelRows(h, [&](int y0, int y1) {
        // Sanitised colour of rows y - r .. y + r, in a ring indexed by row % (2 r + 1)
        // (each chunk sanitises its rows and the r beside it: no full-frame copy).
        std::vector<float>& ring = tRing;
        if (ring.size() < size_t(ringRows) * 3 * w) ring.resize(size_t(ringRows) * 3 * w);
        auto slot = [&](int row, int c) {
            return ring.data() + (size_t(row % ringRows) * 3 + c) * w;
        };
        auto load = [&](int row) {
            for (int c = 0; c < 3; ++c) {
                const float* s = cur.row(c, row);
                float* d = slot(row, c);
                for (int x = 0; x < w; ++x) d[x] = sanitise(s[x]);
            }
        };
        for (int row = std::max(0, y0 - r); row < std::min(h, y0 + r); ++row) load(row);
        std::vector<const float*> win(size_t(ringRows) * 3);
        std::vector<float> ones(len ? 0 : size_t(w), 1.f);  // 1 > 0: valid, as without the input
        for (int y = y0; y < y1; ++y) {
            if (y + r < h) load(y + r);
            const int ya = std::max(0, y - r), yb = std::min(h - 1, y + r);
            RowIo io;
            io.rows = yb - ya + 1;
            io.centre = y - ya;
            for (int c = 0; c < 3; ++c) {
                for (int i = 0; i < io.rows; ++i) win[size_t(c) * ringRows + i] = slot(ya + i, c);
                io.win[c] = win.data() + size_t(c) * ringRows;
            }
            io.h0 = hist->row(0, y);
            io.h1 = hist->row(1, y);
            io.h2 = hist->row(2, y);
            io.len = len ? len->row(0, y) : nullptr;
            io.lenOrOne = len ? io.len : ones.data();
            io.o0 = out.row(0, y);
            io.o1 = out.row(1, y);
            io.o2 = out.row(2, y);
            int x = 0;
            for (; x < std::min(r, w); ++x) edgePixel(prm, w, r, x, io);
            for (; x + kLanes <= w - r; x += kLanes) interiorBlock(prm, r, x, io);
            for (; x < w; ++x) edgePixel(prm, w, r, x, io);
        }
    });
}

}  // namespace
}  // namespace kestrel::passes::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace kestrel::passes {
namespace {
HWY_EXPORT(executeOnTarget);
}  // namespace

ClampedAccumulationPass::Declaration::Declaration()
    : kestrel::Declaration<Params>(
          "ClampedAccumulation",
          "GAMES202 temporal accumulation: alpha*C + (1-alpha)*clamp(history, mu-k*sigma, "
          "mu+k*sigma) over a window of the current colour") {
    color = input("color", Format::Float3, "current (spatially filtered) colour");
    history = optionalInput("history", Format::Float3, "previous output reprojected to this frame");
    historyLength =
        optionalInput("historyLength", Format::Float,
                      "reprojection validity: 0 where the projection failed (alpha = 1 there)");
    colorOut = output("color", Format::Float3, "accumulated colour");
    paramDecimal("alpha", &Params::alpha, 0.0, 1.0,
                 "weight of the current colour where history is valid");
    param("k", &Params::k, 0.0, 1000.0, "half-width of the colour box in standard deviations");
    param("radius", &Params::radius, 0, 32, "window radius of the mean/sigma statistics (3: 7x7)");
    param("holdCurrent", &Params::holdCurrent,
          "widen the box to contain the current colour (off: the homework's box), so "
          "that a history equal to the current colour is never pulled away from it");
}

const ClampedAccumulationPass::Declaration& ClampedAccumulationPass::declaration() {
    static const Declaration d;
    return d;
}

void ClampedAccumulationPass::resolve(ResolveContext& rc) {
    const Declaration& d = declaration();
    if (!rc.isBound(d.history)) {
        rc.forward(d.colorOut, d.color);
        rc.note("no history bound: the output is the current colour");
    }
}

void ClampedAccumulationPass::execute(FrameContext& ctx, PassIO& io) {
    HWY_DYNAMIC_DISPATCH(executeOnTarget)
    (ctx, io, p_.alpha, p_.k, p_.radius, p_.holdCurrent);
}

}  // namespace kestrel::passes
#endif  // HWY_ONCE
