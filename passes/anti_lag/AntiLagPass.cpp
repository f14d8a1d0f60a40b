// Compiled once per SIMD target (hwy/foreach_target.h re-includes this file for each one): the
// scalar loops auto-vectorise for each instruction set; the HWY_ONCE part at the end picks the
// running CPU's best target. No contraction (-ffp-contract=off): every target rounds alike.
#include "AntiLagPass.h"

#include <kestrel/PixelMath.h>
#include <kestrel/Scratch.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "AntiLagPass.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep
#include <hwy/highway.h>
#include <kestrel/SimdMath.h>

HWY_BEFORE_NAMESPACE();
namespace kestrel::HWY_NAMESPACE {
namespace {

namespace hn = hwy::HWY_NAMESPACE;

constexpr float kMaxLength = 1e6f;  // as TemporalAccumulation reads a history length
constexpr int kMaxRadius = AntiLagPass::kMaxRadius;

inline bool validLength(float h) {
    return (h > 0.f) & (h <= std::numeric_limits<float>::max());
}

/// The window statistics of one row's pixels, over the pixels with a valid history only (the
/// current and the history means are compared over the same pixels).
/// Terms: valid (1 or 0), current luminance, its square, the history's luminance.
enum Term { N, C, C2, H, kTerms };
using RowSums = std::array<float*, kTerms>;

inline float luminance(float r, float g, float b) {
    const float l = px::luminance(px::sanitize(r), px::sanitize(g), px::sanitize(b));
    return std::max(l, 0.f);  // emission subtracted from a noisy colour can leave it below 0
}

/// Which pixels have a history, one bit per pixel, each row in whole words (a row's bits are
/// written by one thread): the window reads its neighbours' validity from here, so the lengths
/// can be gated in place (a row's length is then read only by its own pixel, before it is
/// written).
struct ValidMask {
    int words;  ///< per row
    std::vector<uint64_t> bits;
    ValidMask(int w, int h) : words((w + 63) / 64), bits(size_t(words) * size_t(h)) {}
    uint64_t* row(int y) { return bits.data() + size_t(y) * size_t(words); }
    const uint64_t* row(int y) const { return bits.data() + size_t(y) * size_t(words); }
};

/// Whether a vector of `lanes` pixels starting at a multiple of `lanes` has its validity bits in
/// one mask word (the lane count divides 64): the vector paths below need it.
constexpr bool vectorInOneMaskWord(int lanes) {
    return lanes <= 64 && 64 % lanes == 0;
}

/// The per-pixel terms of image row y, written from t[k] + pad on. Explicit vectors: GCC left
/// the selects and sanitisers scalar. Luminance as px::luminance rounds it (products, then sums
/// left to right, no fused multiply-add), so every target gives the same bits.
void rowTerms(const ImageView& color, const ImageView& history, const ValidMask& valid, int y,
              const RowSums& t, int pad) {
    const int w = color.width();
    const float *r = color.row(0, y), *g = color.row(1, y), *b = color.row(2, y),
                *hr = history.row(0, y), *hg = history.row(1, y), *hb = history.row(2, y);
    const uint64_t* vm = valid.row(y);
    float *tn = t[N] + pad, *tc = t[C] + pad, *tc2 = t[C2] + pad, *th = t[H] + pad;
    const hn::ScalableTag<float> d;
    const int lanes = int(hn::Lanes(d));
    const auto kr = hn::Set(d, 0.2126f), kg = hn::Set(d, 0.7152f), kb = hn::Set(d, 0.0722f);
    const auto zero = hn::Zero(d), one = hn::Set(d, 1.f);
    auto lum = [&](const float* pr, const float* pg, const float* pb, int x) HWY_ATTR {
        const auto l = hn::Add(hn::Add(hn::Mul(kr, simd::sanitize(hn::LoadU(d, pr + x))),
                                       hn::Mul(kg, simd::sanitize(hn::LoadU(d, pg + x)))),
                               hn::Mul(kb, simd::sanitize(hn::LoadU(d, pb + x))));
        return hn::Max(zero, l);  // as std::max(l, 0.f): -0 stays -0
    };
    int x = 0;
    // A vector's lanes lie in one mask word: the lane count divides 64.
    if (vectorInOneMaskWord(lanes)) {
        const uint64_t laneBits = lanes == 64 ? ~uint64_t(0) : (uint64_t(1) << lanes) - 1u;
        for (; x + lanes <= w; x += lanes) {
            const uint64_t bits = (vm[x >> 6] >> (x & 63)) & laneBits;
            uint8_t bytes[8];
            for (int i = 0; i < 8; ++i) bytes[i] = uint8_t(bits >> (8 * i));
            const auto v = hn::LoadMaskBits(d, bytes);
            const auto lc = hn::IfThenElseZero(v, lum(r, g, b, x));
            hn::StoreU(hn::IfThenElseZero(v, one), d, tn + x);
            hn::StoreU(lc, d, tc + x);
            hn::StoreU(hn::Mul(lc, lc), d, tc2 + x);
            hn::StoreU(hn::IfThenElseZero(v, lum(hr, hg, hb, x)), d, th + x);
        }
    }
    for (; x < w; ++x) {
        const bool v = (vm[x >> 6] >> (x & 63)) & 1u;
        const float lc = v ? luminance(r[x], g[x], b[x]) : 0.f;
        tn[x] = v ? 1.f : 0.f;
        tc[x] = lc;
        tc2[x] = lc * lc;
        th[x] = v ? luminance(hr[x], hg[x], hb[x]) : 0.f;
    }
}

/// out[x] = src[0][x] + src[1][x] + ... + src[n - 1][x], summed in that order (so the same
/// whichever thread or SIMD target computes it), the sum kept in a register.
void sumRows(const float* const* src, int n, float* out, int w) {
    const hn::ScalableTag<float> d;
    const int lanes = int(hn::Lanes(d));
    int x = 0;
    for (; x + lanes <= w; x += lanes) {
        auto s = hn::LoadU(d, src[0] + x);
        for (int i = 1; i < n; ++i) s = hn::Add(s, hn::LoadU(d, src[i] + x));
        hn::StoreU(s, d, out + x);
    }
    for (; x < w; ++x) {
        float s = src[0][x];
        for (int i = 1; i < n; ++i) s += src[i][x];
        out[x] = s;
    }
}

/// Box sums of half-width r along a row padded with r zeros on each side, summed left to right.
void boxRow(const float* padded, float* out, int w, int r) {
    std::array<const float*, 2 * kMaxRadius + 1> taps;
    for (int i = 0; i <= 2 * r; ++i) taps[size_t(i)] = padded + i;
    sumRows(taps.data(), 2 * r + 1, out, w);
}

/// hl' from hl and the gradient lambda in [0, 1]: the current frame's blend weight a = 1 / (hl + 1)
/// becomes a + (1 - a) lambda (A-SVGF's alpha' = (1 - lambda) alpha + lambda), so
/// hl' = 1 / a' - 1 = hl (1 - lambda) / (1 + lambda hl). lambda = 1 drops the history.
inline float shortened(float hl, float lambda) {
    return hl * (1.f - lambda) / (1.f + lambda * hl);
}

/// The gated length of one pixel from its window sums.
inline float gate(float hl, float n, float c, float c2, float hs, float sigma) {
    n = std::max(n, 1.f);  // the centre is valid; the guard keeps float error from dividing by 0
    const float mc = c / n, mh = hs / n;
    // The current window's spread, not the history's temporal variance: after a light is
    // switched off, the history's variance is the old light's, and hides the change (measured:
    // blender-street with its direct light dimmed 0.15x at frame 7, 30.8 -> 25.1 dB).
    const float stdErr = std::sqrt(std::max(0.f, c2 / n - mc * mc) / n);
    const float excess = std::max(0.f, std::fabs(mh - mc) - sigma * stdErr);
    // Normalised by the smaller mean (A-SVGF: the larger): a relative change, so a light that
    // halves or doubles drops the history. By the larger, a light switched off to 0.15x kept
    // 15% of the old light, as much as the new: frame 6 of the test's switched-off street came
    // out 5x worse than its 1-spp input (relMSE 0.26 against 0.052; 0.0077 by the smaller).
    const float scale = std::min(mh, mc);
    const float lambda = std::min(1.f, excess / std::max(scale, std::numeric_limits<float>::min()));
    return validLength(hl) ? shortened(std::min(hl, kMaxLength), lambda) : 0.f;
}

/// gate() for one row, explicit vectors (the same operations in the same order: IEEE division
/// and square root, no fused multiply-add, so the same bits as the scalar tail).
void gateRow(const float* hl, const RowSums& col, float* o, int w, float sigma) {
    const hn::ScalableTag<float> d;
    const int lanes = int(hn::Lanes(d));
    const auto zero = hn::Zero(d), one = hn::Set(d, 1.f), vsigma = hn::Set(d, sigma);
    const auto tiny = hn::Set(d, std::numeric_limits<float>::min());
    const auto maxLength = hn::Set(d, kMaxLength),
               floatMax = hn::Set(d, std::numeric_limits<float>::max());
    int x = 0;
    for (; x + lanes <= w; x += lanes) {
        const auto n = hn::Max(hn::LoadU(d, col[N] + x), one);
        const auto mc = hn::Div(hn::LoadU(d, col[C] + x), n);
        const auto mh = hn::Div(hn::LoadU(d, col[H] + x), n);
        const auto spread = hn::Sub(hn::Div(hn::LoadU(d, col[C2] + x), n), hn::Mul(mc, mc));
        const auto stdErr = hn::Sqrt(hn::Div(hn::Max(spread, zero), n));
        const auto excess =
            hn::Max(hn::Sub(hn::Abs(hn::Sub(mh, mc)), hn::Mul(vsigma, stdErr)), zero);
        const auto lambda = hn::Min(hn::Div(excess, hn::Max(hn::Min(mh, mc), tiny)), one);
        const auto h = hn::LoadU(d, hl + x);
        const auto valid = hn::And(hn::Gt(h, zero), hn::Le(h, floatMax));
        const auto l = hn::Min(h, maxLength);
        const auto shortened =
            hn::Div(hn::Mul(l, hn::Sub(one, lambda)), hn::Add(one, hn::Mul(lambda, l)));
        hn::StoreU(hn::IfThenElseZero(valid, shortened), d, o + x);
    }
    for (; x < w; ++x) o[x] = gate(hl[x], col[N][x], col[C][x], col[C2][x], col[H][x], sigma);
}

void gateRows(const ImageView& color, const ImageView& history, const ValidMask& valid,
              const ImageView& length, const ImageView& out, const AntiLagPass::Params& s, int y0,
              int y1) {
    const int w = color.width(), h = color.height(), taps = 2 * s.radius + 1;
    // A ring of the window's rows, each summed along x, then the column sums: each row's sums
    // are computed the same way whichever band holds it, and the columns summed in a fixed
    // order, so the result does not depend on how the rows are split between threads.
    auto lease = ScratchPool::acquire(size_t(kTerms * (taps + 2)), size_t(w + 2 * s.radius));
    auto sums = [&](int i) {
        const int b = kTerms * i;
        return RowSums{lease[b], lease[b + 1], lease[b + 2], lease[b + 3]};
    };
    auto ring = [&](int y) { return sums(((y % taps) + taps) % taps); };
    const RowSums col = sums(taps), terms = sums(taps + 1);
    for (float* t : terms) {  // the zero padding of the rows' ends
        std::fill_n(t, s.radius, 0.f);
        std::fill_n(t + s.radius + w, s.radius, 0.f);
    }
    auto enter = [&](int y) {
        rowTerms(color, history, valid, y, terms, s.radius);
        const RowSums r = ring(y);
        for (int k = 0; k < kTerms; ++k) boxRow(terms[k], r[k], w, s.radius);
    };
    for (int y = std::max(0, y0 - s.radius); y < std::min(h, y0 + s.radius); ++y) enter(y);
    for (int y = y0; y < y1; ++y) {
        if (y + s.radius < h) enter(y + s.radius);
        const int top = std::max(0, y - s.radius), bottom = std::min(h - 1, y + s.radius);
        for (int k = 0; k < kTerms; ++k) {
            std::array<const float*, 2 * kMaxRadius + 1> rows;
            for (int yy = top; yy <= bottom; ++yy) rows[size_t(yy - top)] = ring(yy)[k];
            sumRows(rows.data(), bottom - top + 1, col[k], w);
        }
        gateRow(length.row(0, y), col, out.row(0, y), w, s.sigma);
    }
}

/// Rows [y0, y1) of the validity mask: whole vectors where the lane count divides 64 (each
/// vector's bits land in one word), the rest one pixel at a time.
void markValidRows(const ImageView& length, ValidMask& valid, int w, int y0, int y1) {
    const hn::ScalableTag<float> d;
    const int lanes = int(hn::Lanes(d));
    const bool whole = vectorInOneMaskWord(lanes);
    const auto zero = hn::Zero(d), floatMax = hn::Set(d, std::numeric_limits<float>::max());
    for (int y = y0; y < y1; ++y) {
        const float* hl = length.row(0, y);
        uint64_t* vm = valid.row(y);
        int x = 0;
        for (; whole && x + lanes <= w; x += lanes) {
            const auto h = hn::LoadU(d, hl + x);
            uint8_t bytes[8] = {};
            hn::StoreMaskBits(d, hn::And(hn::Gt(h, zero), hn::Le(h, floatMax)), bytes);
            uint64_t bits = 0;
            for (int i = 0; i < 8; ++i) bits |= uint64_t(bytes[i]) << (8 * i);
            vm[x >> 6] |= bits << (x & 63);
        }
        for (; x < w; ++x) vm[x >> 6] |= uint64_t(validLength(hl[x])) << (x & 63);
    }
}

/// The pass for this target.
void executeOnTarget(FrameContext& ctx, PassIO& io, const AntiLagPass::Params& s) {
    const AntiLagPass::Declaration& d = AntiLagPass::declaration();
    const ImageView &color = io.input(d.color), &history = io.input(d.history),
                    &length = io.input(d.historyLength), &out = io.output(d.historyLengthOut);
    const int w = ctx.extent.width;
    ValidMask valid(w, ctx.extent.height);
    ctx.parallelRows(ctx.extent.height,
                     [&](int y0, int y1) { markValidRows(length, valid, w, y0, y1); });
    // Bands of 64 rows: each band first sums the 2 radius rows around it, which rows split
    // finer (the engine's chunks are as small as one row) would repeat several times over.
    constexpr int kBand = 64;
    const int h = ctx.extent.height, bands = (h + kBand - 1) / kBand;
    ctx.parallelRows(bands, [&](int b0, int b1) {
        for (int b = b0; b < b1; ++b)
            gateRows(color, history, valid, length, out, s, b * kBand,
                     std::min(h, (b + 1) * kBand));
    });
}

}  // namespace
}  // namespace kestrel::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace kestrel {
namespace {
HWY_EXPORT(executeOnTarget);
}  // namespace
}  // namespace kestrel

using namespace kestrel;

AntiLagPass::Declaration::Declaration()
    : kestrel::Declaration<Params>(
          "AntiLag",
          "Shortens the reprojected history length where the lighting changed (A-SVGF's "
          "temporal-gradient test): where the window means of the current frame's and of the "
          "history's luminance differ by more than sigma standard errors of the current "
          "mean, the excess over the smaller mean is the gradient lambda (at most 1), and "
          "the current frame's weight 1 / (length + 1) rises as A-SVGF's a' = (1 - lambda) "
          "a + lambda (TemporalAccumulation's alpha floor applies after). "
          "Exposure-independent.") {
    color = input("color", Format::Float3, "this frame's (demodulated) colour");
    history = input("history", Format::Float3, "the reprojected colour history");
    historyLength =
        input("historyLength", Format::Float, "the reprojected history length (0: none)");
    historyLengthOut = output("historyLength", Format::Float,
                              "the history length to accumulate with", &historyLength);
    param("radius", &Params::radius, 1, kMaxRadius, "window half-width in pixels (4: 9x9)");
    param("sigma", &Params::sigma, 0.0, 1e6,
          "standard errors of the current window's mean luminance a difference must "
          "exceed before the history is shortened (higher: fewer false alarms on noise)");
    param("enabled", &Params::enabled,
          "false: the history length passes through unchanged and the pass is left out");
}

const AntiLagPass::Declaration& AntiLagPass::declaration() {
    static const Declaration d;
    return d;
}

void AntiLagPass::resolve(ResolveContext& rc) {
    const Declaration& d = declaration();
    if (!p_.enabled) rc.forward(d.historyLengthOut, d.historyLength);
}

void AntiLagPass::execute(FrameContext& ctx, PassIO& io) {
    HWY_DYNAMIC_DISPATCH(executeOnTarget)(ctx, io, p_);
}
#endif  // HWY_ONCE
