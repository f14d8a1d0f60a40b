// Compiled once per SIMD target (hwy/foreach_target.h re-includes this file for each one):
// the scalar loops auto-vectorise for each instruction set (and std::fma becomes one
// instruction where there is FMA); the HWY_ONCE part at the end picks the running CPU's
// best target.
#include "TaaPass.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <vector>

#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "TaaPass.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep
#include <hwy/highway.h>

HWY_BEFORE_NAMESPACE();
namespace kestrel::passes::HWY_NAMESPACE {
namespace {

constexpr float kMaxValue = 1e18f;  // keeps 3x3 sums of squares finite

inline float sanitise(float v) {
    return v == v ? std::clamp(v, -kMaxValue, kMaxValue) : 0.f;
}

// Floating-point evaluation. The plugin is compiled with -ffp-contract=off and every fused
// multiply-add is spelled out with std::fma: the arithmetic is exactly the one the compiler
// generated for the previous implementation (which contracted some products into FMAs and not
// others), so results are bit-identical to it, and they no longer depend on what a compiler
// version chooses to contract.

// YCoCg (Malvar & Sullivan 2003): a luma/chroma basis where the neighbourhood box fits the
// colour distribution more tightly than RGB (Karis 2014). Products rounded, then summed.
struct Ycc {
    float y, co, cg;
};
inline Ycc toYcc(float r, float g, float b) {
    const float r4 = 0.25f * r, g2 = 0.5f * g, b4 = 0.25f * b;
    return {(r4 + g2) + b4, 0.5f * r - 0.5f * b, (g2 - r4) - b4};
}

struct Params {
    float alpha, gamma;
    bool clip, antiFlicker;
    float blurAlpha;  ///< the current frame's weight where resampleBlur is 1
    bool warmUp;      ///< historyLength is TAA's own age, fed back: weight young histories down
};

constexpr float kMaxAge = 255.f;  // 2 / (age + 1) is far below any alpha by then

// The current frame's least weight in a history of len frames (the age fed back through the
// reprojection; this frame makes it len + 1): 2 / (len + 2). Inverse-variance weights of
// estimates whose variance falls as 1 / k with their age k (a denoiser's output converging
// after a disocclusion or the first frame) weight frame k by k, and the newest of n frames by
// 2 / (n + 1); an exponential blend instead keeps the first, worst frames for long (TAA on a
// static 1.5 px-filtered street: 26.25 dB against 26.62 with these weights).
inline float warmUpAlpha(float len) {
    return 2.f / (std::max(len, 0.f) + 2.f);
}

inline float nextAge(float len) {
    return std::min(len + 1.f, kMaxAge);
}

// One pixel's TAA from its YCoCg colour c, 3x3 neighbourhood sums s1 = sum(q - c),
// s2 = sum((q - c)^2) over n taps, and the YCoCg history hv; returns the YCoCg result.
// Interior: whether the pixel has a full 3x3 window; the blend's final multiply-add is fused on
// the history term there and on the current term at the border (as before).
template <bool Interior>
__attribute__((always_inline)) inline void resolvePixel(const Params& p, const float c[3],
                                                        const float s1[3], const float s2[3],
                                                        float n, float blur, float len, float hv[3],
                                                        float res[3]) {
    float mu[3], lo[3], hi[3];
    for (int ch = 0; ch < 3; ++ch) {
        const float m1 = s1[ch] / n;
        const float ext = p.gamma * std::sqrt(std::max(0.f, std::fma(-m1, m1, s2[ch] / n)));
        mu[ch] = c[ch] + m1;
        // The box always contains the current colour: a lone bright pixel is outside its own
        // mean +- sigma, and clipping it would make TAA dim every small feature (a static scene
        // must converge to the input).
        lo[ch] = std::min(mu[ch] - ext, c[ch]);
        hi[ch] = std::max(mu[ch] + ext, c[ch]);
    }
    if (p.clip) {
        // Move H towards mu until it is inside the box (Pedersen 2016); mu lies inside, so t
        // stays in [0, 1]. H is above the box or below it, never both (lo <= hi, and every
        // comparison with a NaN bound is false), so one quotient per channel: the one the
        // side it leaves by needs. Selects instead of branches; an unselected quotient may be
        // Inf/NaN and is discarded.
        float t = 1.f;
        for (int ch = 0; ch < 3; ++ch) {
            const float off = hv[ch] - mu[ch];
            const bool above = hv[ch] > hi[ch], below = hv[ch] < lo[ch];
            const float q = ((above ? hi[ch] : lo[ch]) - mu[ch]) / off;
            const float tq = std::min(t, q);
            t = above | below ? tq : t;
        }
        for (int ch = 0; ch < 3; ++ch) hv[ch] = std::fma(hv[ch] - mu[ch], t, mu[ch]);
    } else {
        for (int ch = 0; ch < 3; ++ch) hv[ch] = std::clamp(hv[ch], lo[ch], hi[ch]);
    }
    // History resampled between pixel centres is blurred (Karis 2014): its weight falls with
    // the blur the reprojection reports, to blurAlpha's share where it is largest.
    // NaN and values outside [0, 1] (a user's own wiring) count as 0 and 1.
    const float b = blur > 0.f ? std::min(blur, 1.f) : 0.f;
    const float blended = std::fma(b, p.blurAlpha - p.alpha, p.alpha);
    const float alpha = p.warmUp ? std::max(blended, warmUpAlpha(len)) : blended;
    float wc = alpha, wh = 1.f - alpha;
    if (p.antiFlicker) {
        wc /= 1.f + std::max(0.f, c[0]);
        wh /= 1.f + std::max(0.f, hv[0]);
    }
    const float sum = wc + wh;
    const bool pos = sum > 0.f;
    const float wcn = wc / sum, whn = wh / sum;
    wc = pos ? wcn : 1.f;
    wh = pos ? whn : 0.f;
    for (int ch = 0; ch < 3; ++ch)
        res[ch] = Interior ? std::fma(wh, hv[ch], wc * c[ch]) : std::fma(wc, c[ch], wh * hv[ch]);
}

inline void fromYcc(const float v[3], float& r, float& g, float& b) {
    r = v[0] + v[1] - v[2];
    g = v[0] + v[2];
    b = v[0] - v[1] - v[2];
}

// This frame's colour in YCoCg, sanitised, for one row (three planes).
void yccRow(int w, const float* __restrict r, const float* __restrict g, const float* __restrict b,
            float* __restrict y, float* __restrict co, float* __restrict cg) {
    for (int x = 0; x < w; ++x) {
        const Ycc v = toYcc(sanitise(r[x]), sanitise(g[x]), sanitise(b[x]));
        y[x] = v.y;
        co[x] = v.co;
        cg[x] = v.cg;
    }
}

/// The rows one output row reads.
struct RowIo {
    const float* ycc[3][3];     ///< [channel][row y-1, y, y+1] of the YCoCg colour
    const float *cr, *cg, *cb;  ///< this row's colour
    const float *hr, *hg, *hb;  ///< this row's history
    const float* len;           ///< this row's history length, or null (interior: ones)
    const float* blur;          ///< this row's resampling blur, or null (interior: zeros)
    float *o0, *o1, *o2;
    float* age;  ///< this row's historyLength output (TAA's own age; interior: a scratch row)
};

// Interior pixels x in [1, w - 1) of a row with rows above and below: a fixed, branch-free
// 3x3 window and selects, vectorised by the compiler across x.
template <bool Clip, bool AntiFlicker>
void interiorRow(int w, const RowIo& io, const Params& prm) {
    const Params p{prm.alpha, prm.gamma, Clip, AntiFlicker, prm.blurAlpha, prm.warmUp};
    const float *y0 = io.ycc[0][0], *y1 = io.ycc[0][1], *y2 = io.ycc[0][2];
    const float *a0 = io.ycc[1][0], *a1 = io.ycc[1][1], *a2 = io.ycc[1][2];
    const float *b0 = io.ycc[2][0], *b1 = io.ycc[2][1], *b2 = io.ycc[2][2];
    const float *cr = io.cr, *cg = io.cg, *cb = io.cb, *hr = io.hr, *hg = io.hg, *hb = io.hb;
    const float* len = io.len;
    const float* blur = io.blur;
    float *o0 = io.o0, *o1 = io.o1, *o2 = io.o2, *age = io.age;
    constexpr float kFinite = std::numeric_limits<float>::max();
#pragma GCC ivdep
    for (int x = 1; x < w - 1; ++x) {
        // 3x3 sums of one channel, shifted by the centre (taps row by row, left to right).
        // Fused: whether the squares are accumulated with FMAs; they are not for Y and Co
        // (the previous implementation's compiled code summed those two channels as a pair,
        // with rounded products) and are for Cg.
        auto window = [x](const float* r0, const float* r1, const float* r2, bool fused, float& c,
                          float& s1, float& s2) __attribute__((always_inline)) {
            c = r1[x];
            float q1 = 0, q2 = 0;
            for (const float* row : {r0, r1, r2})
                for (int k = -1; k <= 1; ++k) {
                    const float d = row[x + k] - c;
                    q1 += d;
                    q2 = fused ? std::fma(d, d, q2) : q2 + d * d;
                }
            s1 = q1;
            s2 = q2;
        };
        float c[3], s1[3], s2[3];
        window(y0, y1, y2, false, c[0], s1[0], s2[0]);
        window(a0, a1, a2, false, c[1], s1[1], s2[1]);
        window(b0, b1, b2, true, c[2], s1[2], s2[2]);
        const bool valid = (len[x] > 0.f) & (std::fabs(hr[x]) <= kFinite) &
                           (std::fabs(hg[x]) <= kFinite) & (std::fabs(hb[x]) <= kFinite);
        const Ycc v = toYcc(sanitise(hr[x]), sanitise(hg[x]), sanitise(hb[x]));
        float hv[3] = {v.y, v.co, v.cg}, res[3];
        resolvePixel<true>(p, c, s1, s2, 9.f, blur[x], len[x], hv, res);
        float r, g, b;
        fromYcc(res, r, g, b);
        o0[x] = valid ? r : sanitise(cr[x]);
        o1[x] = valid ? g : sanitise(cg[x]);
        o2[x] = valid ? b : sanitise(cb[x]);
        age[x] = valid ? nextAge(len[x]) : 1.f;
    }
}

// One pixel with the window clamped to the image (borders, rows without a neighbour).
// io.ycc[ch][0..2]: rows y-1, y, y+1 (null where outside the image).
void borderPixel(int x, int w, int ya, int yb, int y, const RowIo& io, const Params& p) {
    const float* lenRow = io.len;
    const bool valid = (!lenRow || lenRow[x] > 0.f) && std::isfinite(io.hr[x]) &&
                       std::isfinite(io.hg[x]) && std::isfinite(io.hb[x]);
    if (io.age) io.age[x] = valid ? nextAge(lenRow ? lenRow[x] : 1.f) : 1.f;
    if (!valid) {  // disoccluded: exactly the current colour
        io.o0[x] = sanitise(io.cr[x]);
        io.o1[x] = sanitise(io.cg[x]);
        io.o2[x] = sanitise(io.cb[x]);
        return;
    }
    const float c[3] = {io.ycc[0][1][x], io.ycc[1][1][x], io.ycc[2][1][x]};
    const Ycc v = toYcc(sanitise(io.hr[x]), sanitise(io.hg[x]), sanitise(io.hb[x]));
    float hv[3] = {v.y, v.co, v.cg}, res[3];
    // 3x3 mean and standard deviation, shifted by the centre for precision.
    const int xa = std::max(0, x - 1), xb = std::min(w - 1, x + 1);
    const float n = float((yb - ya + 1) * (xb - xa + 1));
    float s1[3], s2[3];
    for (int ch = 0; ch < 3; ++ch) {
        float a1 = 0, a2 = 0;
        for (int yy = ya; yy <= yb; ++yy) {
            const float* p = io.ycc[ch][yy - y + 1];
            for (int xx = xa; xx <= xb; ++xx) {
                const float d = p[xx] - c[ch];
                a1 += d;
                a2 = std::fma(d, d, a2);
            }
        }
        s1[ch] = a1;
        s2[ch] = a2;
    }
    resolvePixel<false>(p, c, s1, s2, n, io.blur ? io.blur[x] : 0.f, lenRow ? lenRow[x] : 1.f, hv,
                        res);
    fromYcc(res, io.o0[x], io.o1[x], io.o2[x]);
}

// Per-thread scratch: three YCoCg rows (ring), reused across chunks and frames.
thread_local std::vector<float> tYcc;

/// The pass's bound images; null where an input is not bound or an output not consumed.
struct Views {
    const ImageView &cur, &out;
    const ImageView *hist, *len, *blur, *age;
};

Views bind(PassIO& io) {
    const TaaPass::Declaration& d = TaaPass::declaration();
    auto in = [&](const InputPort& p) { return io.has(p) ? &io.input(p) : nullptr; };
    return {
        io.input(d.color),  io.output(d.colorOut),
        in(d.history),      in(d.historyLength),
        in(d.resampleBlur), io.has(d.historyLengthOut) ? &io.output(d.historyLengthOut) : nullptr};
}

/// Rows [ya, yb) without a history: exactly the current colour, and an age of 1.
void passThroughRows(const Views& v, int w, int ya, int yb) {
    for (int y = ya; y < yb; ++y) {
        for (int ch = 0; ch < 3; ++ch) {
            const float* s = v.cur.row(ch, y);
            float* d = v.out.row(ch, y);
            for (int x = 0; x < w; ++x) d[x] = sanitise(s[x]);
        }
        if (v.age) std::fill(v.age->row(0, y), v.age->row(0, y) + w, 1.f);
    }
}

/// The rows output row y reads; slot(row, ch) is a row's YCoCg channel.
template <class Slot>
RowIo rowIo(const Views& v, int y, int h, Slot slot) {
    const int ra = std::max(0, y - 1), rb = std::min(h - 1, y + 1);
    RowIo r;
    for (int ch = 0; ch < 3; ++ch)
        for (int k = 0; k < 3; ++k) {
            const int row = y - 1 + k;
            r.ycc[ch][k] = row >= ra && row <= rb ? slot(row, ch) : nullptr;
        }
    r.cr = v.cur.row(0, y);
    r.cg = v.cur.row(1, y);
    r.cb = v.cur.row(2, y);
    r.hr = v.hist->row(0, y);
    r.hg = v.hist->row(1, y);
    r.hb = v.hist->row(2, y);
    r.len = v.len ? v.len->row(0, y) : nullptr;
    r.blur = v.blur ? v.blur->row(0, y) : nullptr;
    r.o0 = v.out.row(0, y);
    r.o1 = v.out.row(1, y);
    r.o2 = v.out.row(2, y);
    r.age = v.age ? v.age->row(0, y) : nullptr;
    return r;
}

/// One row with a history: the interior vectorised, the border pixels with the window clamped.
/// ones, zeros, ageSink: the history length, resampling blur and age rows where not bound.
void resolveRow(int w, int h, int y, RowIo r, const Params& prm, const float* ones,
                const float* zeros, float* ageSink) {
    const int ra = std::max(0, y - 1), rb = std::min(h - 1, y + 1);
    if (y == 0 || y == h - 1 || w < 3) {
        for (int x = 0; x < w; ++x) borderPixel(x, w, ra, rb, y, r, prm);
        return;
    }
    borderPixel(0, w, ra, rb, y, r, prm);
    if (!r.len) r.len = ones;  // 1 > 0: valid, as without the input
    if (!r.blur) r.blur = zeros;
    if (!r.age) r.age = ageSink;
    if (prm.clip)
        prm.antiFlicker ? interiorRow<true, true>(w, r, prm) : interiorRow<true, false>(w, r, prm);
    else
        prm.antiFlicker ? interiorRow<false, true>(w, r, prm)
                        : interiorRow<false, false>(w, r, prm);
    borderPixel(w - 1, w, ra, rb, y, r, prm);
}

/// The pass for this target (its parameters as arguments).
void executeOnTarget(FrameContext& ctx, PassIO& io, const TaaPass::Params& params) {
    const Views v = bind(io);
    const int w = v.cur.width(), h = v.cur.height();
    // The age is only meaningful where historyLength is the fed-back age.
    const Params prm{params.alpha,       params.gamma,     params.mode == TaaPass::Mode::Clip,
                     params.antiFlicker, params.blurAlpha, params.warmUp && v.len != nullptr};

    ctx.parallelRows(h, [&](int ya, int yb) {
        if (!v.hist) return passThroughRows(v, w, ya, yb);
        // YCoCg of rows y-1, y, y+1 in a ring of three row slots (each chunk converts its
        // rows and the two beside it: no full-frame buffer).
        std::vector<float>& ring = tYcc;
        if (ring.size() < size_t(w) * 12) ring.resize(size_t(w) * 12);
        float* ones = ring.data() + size_t(w) * 9;  // the history length when not fed
        std::fill(ones, ones + w, 1.f);
        float* zeros = ones + w;  // the resampling blur when not fed
        std::fill(zeros, zeros + w, 0.f);
        float* ageSink = zeros + w;  // the interior's age when historyLength is not consumed
        auto slot = [&](int row, int ch) { return ring.data() + (size_t(row % 3) * 3 + ch) * w; };
        auto convert = [&](int row) {
            yccRow(w, v.cur.row(0, row), v.cur.row(1, row), v.cur.row(2, row), slot(row, 0),
                   slot(row, 1), slot(row, 2));
        };
        if (ya > 0) convert(ya - 1);
        convert(ya);
        for (int y = ya; y < yb; ++y) {
            if (y + 1 < h) convert(y + 1);
            resolveRow(w, h, y, rowIo(v, y, h, slot), prm, ones, zeros, ageSink);
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

TaaPass::Declaration::Declaration()
    : kestrel::Declaration<Params>(
          "TAA",
          "Temporal anti-aliasing: blends the reprojected previous output, clipped to the "
          "current 3x3 neighbourhood in YCoCg, with the current colour") {
    color = input("color", Format::Float3, "current frame colour");
    history =
        optionalInput("history", Format::Float3,
                      "previous TAA output reprojected to this frame (Catmull-Rom resampled)");
    historyLength =
        optionalInput("historyLength", Format::Float,
                      "reprojection validity: 0 where disoccluded (history dropped there)");
    colorOut =
        output("color", Format::Float3, "anti-aliased colour (feed back through a history edge)");
    historyLengthOut =
        output("historyLength", Format::Float,
               "frames in the result: historyLength + 1 where the history was used (at most "
               "255), else 1; fed back through the reprojection's prevHistoryLength for warmUp");
    resampleBlur =
        optionalInput("resampleBlur", Format::Float,
                      "how much resampling blurred the history, in [0, 1] (Reprojection's "
                      "resampleBlur): the current frame's weight rises towards blurAlpha "
                      "with it");
    paramDecimal("alpha", &Params::alpha, 0.0, 1.0, "weight of the current frame in the blend");
    paramDecimal("blurAlpha", &Params::blurAlpha, 0.0, 1.0,
                 "weight of the current frame where the history was resampled midway between "
                 "pixels (resampleBlur 1)");
    paramDecimal("gamma", &Params::gamma, 0.0, 100.0,
                 "neighbourhood box half-width in standard deviations (variance clipping)");
    param("mode", &Params::mode, {"clip", "clamp"},
          "clip: move the history towards the mean onto the box; clamp: per channel");
    param("onlyAntiAliased", &Params::onlyAntiAliased,
          "leave TAA out (pass the colour through) unless the source states the render "
          "is anti-aliased (the scene fact antiAliased): on a point-sampled render "
          "judged against a point-sampled reference the history has no detail to add");
    param("warmUp", &Params::warmUp,
          "historyLength is this pass's own historyLength output, fed back through the "
          "reprojection: the current frame's weight is at least 2 / (n + 1) in a history "
          "of n frames (inverse-variance weights of an input whose noise falls as 1/n, as "
          "a denoiser's does after a disocclusion), so the first frames do not linger");
    param("antiFlicker", &Params::antiFlicker,
          "inverse-luminance blend weights (Karis 2014): damps flicker of bright pixels");
}

const TaaPass::Declaration& TaaPass::declaration() {
    static const Declaration d;
    return d;
}

void TaaPass::resolve(ResolveContext& rc) {
    const Declaration& d = declaration();
    if (p_.onlyAntiAliased && rc.fact("antiAliased") != "true") {
        rc.forward(d.colorOut, d.color);
        rc.setAbsent(d.historyLengthOut, "TAA is left out");
        rc.note("point-sampled render: TAA left out (onlyAntiAliased)");
        return;
    }
    if (!rc.isBound(d.history)) {
        rc.forward(d.colorOut, d.color);
        rc.setAbsent(d.historyLengthOut, "no history bound");
        rc.note("no history bound: TAA passes the current colour through");
    }
}

void TaaPass::execute(FrameContext& ctx, PassIO& io) {
    HWY_DYNAMIC_DISPATCH(executeOnTarget)(ctx, io, p_);
}

}  // namespace kestrel::passes
#endif  // HWY_ONCE
