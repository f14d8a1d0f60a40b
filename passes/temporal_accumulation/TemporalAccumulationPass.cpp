// Compiled once per SIMD target (hwy/foreach_target.h re-includes this file for each one):
// the scalar loops auto-vectorise for each instruction set (and std::fma becomes one
// instruction where there is FMA); the HWY_ONCE part at the end picks the running CPU's
// best target.
#include "TemporalAccumulationPass.h"

#include <kestrel/PixelMath.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <type_traits>
#include <vector>

#include "FireflySpread.h"

#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "TemporalAccumulationPass.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep
#include <hwy/highway.h>

HWY_BEFORE_NAMESPACE();
namespace kestrel::HWY_NAMESPACE {
namespace {

// Floating-point evaluation. The plugin is compiled with -ffp-contract=off and every fused
// multiply-add is spelled out with std::fma: the arithmetic is exactly the one the compiler
// generated for the previous implementation, so results are bit-identical to it, and they no
// longer depend on what a compiler version chooses to contract.

// Luminance of the sanitised colour, one row: products rounded, summed left to right. Frames
// narrower than 4 pixels fuse the first product into the first sum (the previous build's
// scalar loop for short rows did; its vectorised loop did not).
void luminanceRow(int w, const float* __restrict r, const float* __restrict g,
                  const float* __restrict b, float* __restrict l) {
    if (w < 4) {
        for (int x = 0; x < w; ++x)
            l[x] = std::fma(0.2126f, px::sanitize(r[x]), 0.7152f * px::sanitize(g[x])) +
                   0.0722f * px::sanitize(b[x]);
        return;
    }
    for (int x = 0; x < w; ++x)
        l[x] = 0.2126f * px::sanitize(r[x]) + 0.7152f * px::sanitize(g[x]) +
               0.0722f * px::sanitize(b[x]);
}

struct Params {
    float alpha, momentsAlpha, cap, k;
};

/// One row's planes. Inputs that are not fed point at neutral rows (see execute); outputs that
/// are not consumed at scratch rows.
struct Row {
    const float *c0, *c1, *c2;    ///< colour
    const float *p0, *p1, *p2;    ///< reprojected colour history
    const float *pm0, *pm1, *pl;  ///< reprojected moments, history length
    const float *lu, *lc, *ld;    ///< luminance of rows y-1, y, y+1 (row y outside the image)
    bool up, down;                ///< whether rows y-1, y+1 exist
    float *o0, *o1, *o2, *om0, *om1, *oh, *ov;
    float *e0, *e1, *e2;  ///< the clamped excess, times its weight (FireflySpread.h)
    float* eb;            ///< the clamp's bound, times the same weight
};

// The per-pixel formula after the firefly neighbourhood statistics: s1, s2 = sum of the n
// neighbours' luminance and of its squares (n > 0), or bound0 = 1e30 when there are none.
// HasC, HasM: prevColor, prevMoments fed (and prevHistoryLength).
template <bool HasC, bool HasM, bool Keep>
__attribute__((always_inline)) inline void pixel(Params p, const Row& r, int x, float s1, float s2,
                                                 float n, bool noNeighbours) {
    // Parameters as values (std::max/min return references: no loads under a mask).
    const float alpha = p.alpha, momentsAlpha = p.momentsAlpha, cap = p.cap, k = p.k;
    float c0 = px::sanitize(r.c0[x]), c1 = px::sanitize(r.c1[x]), c2 = px::sanitize(r.c2[x]);
    float l = r.lc[x];
    const float hRaw = r.pl[x];
    const float hPrev = px::sanitizePositive(hRaw, 1e6f);  // 0 without a history length
    // hPrev > 0, from the raw value (the same set: sanitizePositive keeps exactly the positive
    // finite values positive); a comparison of the input keeps the mask vectorisable.
    const bool valid = (hRaw > 0.f) & (hRaw <= std::numeric_limits<float>::max());
    const bool useM = HasM && valid;
    const float pm0 = px::sanitize(r.pm0[x]), pm1 = px::sanitizePositive(r.pm1[x], 1e32f);
    const float m1p = useM ? pm0 : 0.f, m2p = useM ? pm1 : 0.f;
    const bool useC = HasC && valid;
    const float hl = valid ? std::min(cap, hPrev + 1.f) : 1.f;
    const float ac = std::max(alpha, 1.f / hl), am = std::max(momentsAlpha, 1.f / hl);
    // Firefly clamp: against the mean + k' sigma of the 8 neighbours (the centre excluded) and,
    // where the history is valid, of the history's own moments. Selects, no branches. k' = k / w,
    // w the weight the sample enters the colour with (1 without a history, down to alpha with a
    // long one): what one sample moves the accumulated colour is held to k sigma whatever the
    // history. A fixed k clamped every bright sample of a heavy-tailed 1-spp signal against its
    // mostly dark neighbours, darkening the showroom's indirect light by 19% (out/ref mean 0.81).
    const float ke = k / (useC ? ac : 1.f);
    const float mu = s1 / n;
    const float nb = std::fma(std::sqrt(std::max(0.f, std::fma(-mu, mu, s2 / n))), ke, mu);
    const float sh = std::sqrt(std::max(0.f, std::fma(-m1p, m1p, m2p)));  // the history's sigma
    const float hb = std::fma(sh, ke, m1p);
    float bound = noNeighbours ? 1e30f : nb;
    bound = useM ? std::max(bound, hb) : bound;
    const bool clamp = (k > 0.f) & (l > 0.f) & (l > bound);
    const float bz = std::max(bound, 0.f), s = bz / l;
    // What the clamp takes off, as it would have entered the accumulation; kept only where the
    // history is valid (a sample with none is its own pixel's whole colour: spreading it
    // restored the noise the clamp removed, 0.1 dB on the zoo street's flat walls).
    const float ew = (clamp & useC) ? (1.f - s) * ac : 0.f;
    if constexpr (Keep) {  // only when spreading: 8-15% of the pass's time otherwise
        r.e0[x] = c0 * ew;
        r.e1[x] = c1 * ew;
        r.e2[x] = c2 * ew;
        r.eb[x] = (clamp & useC) ? bz * ac : 0.f;
    }
    c0 = clamp ? c0 * s : c0;
    c1 = clamp ? c1 * s : c1;
    c2 = clamp ? c2 * s : c2;
    // A clamped sample enters the moments at l - b, held to [b, 2b]: one far above the bound
    // raises its own history bound, so a sample that recurs (a noise-free highlight under a still
    // camera, a glint) passes within a few frames where at b it stayed at the neighbours' level
    // for good; a noise tail (l <= 2b) enters at b as before, a one-off firefly at most at 2b.
    l = clamp ? std::min(std::max(l - bz, bz), 2.f * bz) : l;
    // Dark clamp: a negative sample below the history's mean - k' sigma (a valid history only:
    // the neighbours of a damaged block are as damaged) is scaled to that bound, at most 0. A
    // -1e10 sample entered unclamped and held the history negative for frames, spreading.
    const float low = std::min(std::fma(-ke, sh, m1p), 0.f);
    const bool dark = (k > 0.f) & useM & (l < low);
    const float sd = dark ? low / l : 1.f;  // l < low <= 0: in [0, 1)
    c0 *= sd;
    c1 *= sd;
    c2 *= sd;
    l = dark ? low : l;
    const float q0 = px::sanitize(r.p0[x]), q1 = px::sanitize(r.p1[x]), q2 = px::sanitize(r.p2[x]);
    r.o0[x] = useC ? std::fma(ac, c0 - q0, q0) : c0;
    r.o1[x] = useC ? std::fma(ac, c1 - q1, q1) : c1;
    r.o2[x] = useC ? std::fma(ac, c2 - q2, q2) : c2;
    const float l2 = l * l;
    const float m1 = useM ? std::fma(am, l - m1p, m1p) : l;
    const float m2 = useM ? std::fma(am, l2 - m2p, m2p) : l2;
    r.om0[x] = m1;
    r.om1[x] = m2;
    r.oh[x] = hl;
    r.ov[x] = std::max(0.f, std::fma(-m1, m1, m2));
}

// Pixels x in [1, w - 1) of a row with rows above and below: all 8 neighbours exist, summed in
// a fixed order (row by row, left to right) with no bounds checks; vectorised across x.
template <bool HasC, bool HasM, bool Keep>
__attribute__((noinline)) void interiorRow(int w, Params p, const Row& row) {
    const Row r = row;  // a local copy: the row pointers stay in registers
    const float *lu = r.lu, *lc = r.lc, *ld = r.ld;
#pragma GCC ivdep
    for (int x = 1; x < w - 1; ++x) {
        float s1 = 0.f, s2 = 0.f;
        auto add = [&](float q) __attribute__((always_inline)) {
            s1 += q;
            s2 = std::fma(q, q, s2);
        };
        add(lu[x - 1]);
        add(lu[x]);
        add(lu[x + 1]);
        add(lc[x - 1]);
        add(lc[x + 1]);
        add(ld[x - 1]);
        add(ld[x]);
        add(ld[x + 1]);
        pixel<HasC, HasM, Keep>(p, r, x, s1, s2, 8.f, false);
    }
}

// A pixel at the image border: the neighbours that exist.
template <bool HasC, bool HasM, bool Keep>
void borderPixel(int w, int x, const Params& p, const Row& r) {
    float s1 = 0.f, s2 = 0.f;
    int n = 0;
    const float* rows[3] = {r.lu, r.lc, r.ld};
    const bool exists[3] = {r.up, true, r.down};
    for (int j = 0; j < 3; ++j) {
        if (!exists[j]) continue;
        for (int i = -1; i <= 1; ++i) {
            const int xx = x + i;
            if ((i == 0 && j == 1) || xx < 0 || xx >= w) continue;
            const float q = rows[j][xx];
            s1 += q;
            s2 = std::fma(q, q, s2);
            ++n;
        }
    }
    pixel<HasC, HasM, Keep>(p, r, x, s1, s2, float(std::max(n, 1)), n == 0);
}

// Per-thread scratch: three luminance rows (ring), neutral input rows and output sinks.
thread_local std::vector<float> tScratch;

/// The pass's bound images; null where an input is not fed or an output not consumed.
struct Views {
    const ImageView& color;
    const ImageView *prevC, *prevM, *prevH;
    const ImageView& outC;
    const ImageView *outM, *outH, *outV;
    firefly::Excess* excess;  ///< where the clamp's excess goes (null: dropped)
};

Views bind(PassIO& io, firefly::Excess* excess) {
    const TemporalAccumulationPass::Declaration& d = TemporalAccumulationPass::declaration();
    // Colour and moments histories are used only with a history length.
    const bool hasHist = io.has(d.prevHistoryLength);
    auto in = [&](const InputPort& p) { return hasHist && io.has(p) ? &io.input(p) : nullptr; };
    auto out = [&](const OutputPort& p) { return io.has(p) ? &io.output(p) : nullptr; };
    return {io.input(d.color),       in(d.prevColor),       in(d.prevMoments),
            in(d.prevHistoryLength), io.output(d.colorOut), out(d.moments),
            out(d.historyLength),    out(d.variance),       excess};
}

/// Row y's planes: `zeros` for the inputs not fed (history length 0 makes every pixel
/// history-less, colour and moments are then not used), `sink` for the outputs not consumed;
/// lum(y) is row y's luminance.
template <class Lum>
Row rowAt(const Views& v, int y, int h, Lum lum, const float* zeros, float* const* sink) {
    Row r;
    r.c0 = v.color.row(0, y);
    r.c1 = v.color.row(1, y);
    r.c2 = v.color.row(2, y);
    r.p0 = v.prevC ? v.prevC->row(0, y) : zeros;
    r.p1 = v.prevC ? v.prevC->row(1, y) : zeros;
    r.p2 = v.prevC ? v.prevC->row(2, y) : zeros;
    r.pm0 = v.prevM ? v.prevM->row(0, y) : zeros;
    r.pm1 = v.prevM ? v.prevM->row(1, y) : zeros;
    r.pl = v.prevH ? v.prevH->row(0, y) : zeros;
    r.up = y > 0;
    r.down = y + 1 < h;
    r.lu = lum(r.up ? y - 1 : y);
    r.lc = lum(y);
    r.ld = lum(r.down ? y + 1 : y);
    r.o0 = v.outC.row(0, y);
    r.o1 = v.outC.row(1, y);
    r.o2 = v.outC.row(2, y);
    r.om0 = v.outM ? v.outM->row(0, y) : sink[0];
    r.om1 = v.outM ? v.outM->row(1, y) : sink[1];
    r.oh = v.outH ? v.outH->row(0, y) : sink[2];
    r.ov = v.outV ? v.outV->row(0, y) : sink[3];
    r.e0 = sink[4];  // the clamp's excess: gathered into Views::excess after the row (keep)
    r.e1 = sink[5];
    r.e2 = sink[6];
    r.eb = sink[7];
    return r;
}

/// One row: the interior vectorised, the border pixels with the neighbours that exist.
template <bool C, bool M, bool K>
void runRow(int w, int h, int y, const Params& prm, const Row& r) {
    if (y == 0 || y == h - 1 || w < 3) {
        for (int x = 0; x < w; ++x) borderPixel<C, M, K>(w, x, prm, r);
        return;
    }
    borderPixel<C, M, K>(w, 0, prm, r);
    interiorRow<C, M, K>(w, prm, r);
    borderPixel<C, M, K>(w, w - 1, prm, r);
}

/// The samples of a row the clamp took something off, in x order (FireflySpread.h): those with
/// a positive bound (a bound of 0 lets nothing be spread).
void keep(const Row& r, int w, std::vector<firefly::Clamped>& out) {
    for (int x = 0; x < w; ++x)
        if (r.eb[x] > 0.f && (r.e0[x] != 0.f || r.e1[x] != 0.f || r.e2[x] != 0.f))
            out.push_back({x, r.e0[x], r.e1[x], r.e2[x], r.eb[x]});
}

/// The pass for this target (its parameters as arguments).
void executeOnTarget(FrameContext& ctx, PassIO& io, const TemporalAccumulationPass::Params& p,
                     firefly::Excess* excess) {
    const int w = ctx.extent.width, h = ctx.extent.height;
    const Views v = bind(io, excess);
    const Params prm{p.alpha, p.momentsAlpha, p.maxHistoryLength, p.fireflySigma};
    const bool hasC = v.prevC != nullptr, hasM = v.prevM != nullptr;
    // Keep (the clamp's excess written for FireflySpread) only where the history is used: a
    // pixel without one keeps nothing (useC false), so hasC false never needs it.
    auto run = hasC ? (excess ? (hasM ? runRow<true, true, true> : runRow<true, false, true>)
                              : (hasM ? runRow<true, true, false> : runRow<true, false, false>))
                    : (hasM ? runRow<false, true, false> : runRow<false, false, false>);

    ctx.parallelRows(h, [&](int ya, int yb) {
        // Scratch rows: 3 luminance (ring), 1 zeros, 8 output sinks (see rowAt).
        std::vector<float>& sc = tScratch;
        if (sc.size() < size_t(w) * 12) sc.resize(size_t(w) * 12);
        auto lumRow = [&](int y) { return sc.data() + size_t(y % 3) * w; };
        float* zeros = sc.data() + size_t(3) * w;
        std::fill(zeros, zeros + w, 0.f);
        float* sink[8] = {zeros + w,
                          zeros + 2 * size_t(w),
                          zeros + 3 * size_t(w),
                          zeros + 4 * size_t(w),
                          zeros + 5 * size_t(w),
                          zeros + 6 * size_t(w),
                          zeros + 7 * size_t(w),
                          zeros + 8 * size_t(w)};
        auto convert = [&](int y) {
            luminanceRow(w, v.color.row(0, y), v.color.row(1, y), v.color.row(2, y), lumRow(y));
        };
        if (ya > 0) convert(ya - 1);
        convert(ya);
        for (int y = ya; y < yb; ++y) {
            if (y + 1 < h) convert(y + 1);
            const Row r = rowAt(v, y, h, lumRow, zeros, sink);
            run(w, h, y, prm, r);
            if (v.excess && hasC) keep(r, w, v.excess->rows[size_t(y)]);
        }
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

TemporalAccumulationPass::Declaration::Declaration()
    : kestrel::Declaration<Params>(
          "TemporalAccumulation",
          "SVGF temporal filter: blends the illumination and its luminance moments with the"
          " reprojected history (alpha = max(alpha, 1/historyLength)); outputs the temporal"
          " variance. Fireflies are clamped before they enter the history.") {
    color = input("color", Format::Float3, "current (demodulated) illumination");
    prevColor = optionalInput("prevColor", Format::Float3, "reprojected history illumination");
    prevMoments =
        optionalInput("prevMoments", Format::Float2, "reprojected history moments (l, l^2)");
    prevHistoryLength =
        optionalInput("prevHistoryLength", Format::Float,
                      "reprojected history length; 0 (or unbound) means no history");
    // pointwise on both pairs: each pixel's history is read before it is written
    colorOut = output("color", Format::Float3, "accumulated illumination", &prevColor);
    moments = output("moments", Format::Float2, "accumulated luminance moments (l, l^2)");
    historyLength = output("historyLength", Format::Float,
                           "min(maxHistoryLength, prev + 1), 1 without history");
    variance = output("variance", Format::Float, "temporal luminance variance max(0, m2 - m1^2)",
                      &prevHistoryLength);
    paramDecimal("alpha", &Params::alpha, 0.0, 1.0, "minimum blend weight of the current colour");
    paramDecimal("momentsAlpha", &Params::momentsAlpha, 0.0, 1.0,
                 "minimum blend weight of the current moments");
    paramDecimal("maxHistoryLength", &Params::maxHistoryLength, 1.0, 1e6,
                 "cap of the history length");
    depth = optionalInput("depth", Format::Float,
                          "linear depth: with normal, the surface the firefly clamp's excess may "
                          "be spread over (fireflySpread)");
    normal = optionalInput("normal", Format::Float3, "world normal (see depth)");
    objectId =
        optionalInput("objectId", Format::Int32, "object id: the excess stays on its object");
    param("fireflySpread", &Params::fireflySpread, 0, firefly::kMaxRadius,
          "radius in px over which what the firefly clamp takes off a sample with a "
          "history is spread on the same surface (depth, normal, object id) instead of "
          "dropped, in the share fireflyFullShare sets (0 = dropped; needs depth and normal)");
    paramDecimal("fireflyFullShare", &Params::fireflyFullShare, 1e-6, 1.0,
                 "the clamped share of a window's light at which all the excess is spread; "
                 "below it, the spread part falls linearly (a noise tail is dropped, light "
                 "the 1-spp frames reach only rarely is kept)");
    paramDecimal("fireflySigma", &Params::fireflySigma, 0.0, 1e6,
                 "firefly clamp: a sample brighter than mean + k*stddev of its 8 neighbours AND"
                 " of its own history is scaled down to that bound, a negative sample below"
                 " mean - k*stddev of its history up to it, at most 0 (k = this; 0 = off)");
}

const TemporalAccumulationPass::Declaration& TemporalAccumulationPass::declaration() {
    static const Declaration d;
    return d;
}

void TemporalAccumulationPass::execute(FrameContext& ctx, PassIO& io) {
    const Declaration& d = declaration();
    const bool spread = p_.fireflySpread > 0 && p_.fireflySigma > 0.f && io.has(d.depth) &&
                        io.has(d.normal) && io.has(d.prevHistoryLength);
    if (spread) excess_.reset(ctx.extent.height);
    HWY_DYNAMIC_DISPATCH(executeOnTarget)(ctx, io, p_, spread ? &excess_ : nullptr);
    if (!spread) return;
    const firefly::Surface surface{&io.input(d.depth), &io.input(d.normal),
                                   io.has(d.objectId) ? &io.input(d.objectId) : nullptr};
    const firefly::SpreadSettings settings{p_.fireflySpread, firefly::kMaxBoundsPerPixel,
                                           p_.fireflyFullShare};
    firefly::spreadExcess(ctx, excess_, surface, settings, io.output(d.colorOut));
}

#endif  // HWY_ONCE
