// Compiled once per SIMD target (hwy/foreach_target.h re-includes this file for each one): the
// fast path lives in kestrel::N_<TARGET>; the HWY_ONCE part at the end picks the running CPU's
// best target.
#include "VarianceEstimationPass.h"

#include <kestrel/PixelMath.h>
#include <kestrel/Scratch.h>

#include <cstdio>
#include <span>
#include <string>
#include <vector>

#include "VarianceReference.h"

#ifndef KESTREL_VARIANCE_INPUTS_
#define KESTREL_VARIANCE_INPUTS_
namespace {
constexpr int kRadius = 3;  // 7x7 (SVGF section 4.2)

/// The geometry and settings shared by the signals filtered together.
struct Inputs {
    int w, h;
    const kestrel::ImageView *depth, *normal;
    const int32_t* ids;
    float sigmaZ, sigmaN, invSigmaL;
};

/// One signal's images (a fused pair filters two with the same weights: VarianceEstimation has
/// no luminance term by default, so its weights are the geometry's alone).
struct Signal {
    const kestrel::ImageView *color, *moments, *hist, *var;
    const kestrel::ImageView* outC;
    const kestrel::ImageView* outV;  ///< null where the variance is not consumed
    float minHist;
};
}  // namespace
#endif

#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "VarianceEstimationPass.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep
// After foreach_target.h: once per target.
#include <hwy/highway.h>
#include <kestrel/SimdMath.h>

HWY_BEFORE_NAMESPACE();
namespace kestrel::HWY_NAMESPACE {
namespace {

namespace hn = hwy::HWY_NAMESPACE;
using simd::DF;
using simd::DI;
using simd::MF;
using simd::VF;
using simd::VI;

/// The spatial estimate of one pixel, plain scalar code: used where a vector block would read
/// outside the image (the first and last columns, the row's tail).
void estimatePixel(const Inputs& in, const Signal& sig, int x, int y, float hl, float* c3,
                   float* v) {
    const int w = in.w, h = in.h;
    auto col = [&](int c, int xq, int yq) { return px::sanitize(sig.color->at(c, xq, yq)); };
    auto lum = [&](int xq, int yq) {
        return px::luminance(col(0, xq, yq), col(1, xq, yq), col(2, xq, yq));
    };
    auto z = [&](int xq, int yq) { return px::sanitizeDepth(in.depth->at(0, xq, yq)); };
    auto nrm = [&](int c, int xq, int yq) { return px::sanitizeNormal(in.normal->at(c, xq, yq)); };
    const bool l = x > 0, r = x + 1 < w, u = y > 0, d = y + 1 < h;
    const float zp = z(x, y), lp = lum(x, y);
    const float gx = px::minAbsDiff(l ? z(x - 1, y) : 0, zp, r ? z(x + 1, y) : 0, l, r);
    const float gy = px::minAbsDiff(u ? z(x, y - 1) : 0, zp, d ? z(x, y + 1) : 0, u, d);
    const float np[3] = {nrm(0, x, y), nrm(1, x, y), nrm(2, x, y)};
    const int32_t* ids = in.ids;
    const int32_t idp = ids ? ids[size_t(y) * size_t(w) + size_t(x)] : 0;
    float sw = 0, sc[3] = {0, 0, 0}, m1 = 0, m2 = 0;
    for (int j = -kRadius; j <= kRadius; ++j) {
        const int yq = y + j;
        if (yq < 0 || yq >= h) continue;
        for (int i = -kRadius; i <= kRadius; ++i) {
            const int xq = x + i;
            if (xq < 0 || xq >= w) continue;
            float wt = 1.f;  // the centre always counts fully
            if (i != 0 || j != 0) {
                if (ids && ids[size_t(yq) * size_t(w) + size_t(xq)] != idp) continue;
                // Same edge-stopping functions as A-Trous (SVGF eq. 3-4), luminance on the raw
                // difference (no variance yet: that is what we estimate).
                const float ez =
                    std::fabs(zp - z(xq, yq)) /
                    (in.sigmaZ * std::fabs(gx * float(i) + gy * float(j)) + 1e-5f * zp + 1e-8f);
                const float el = std::fabs(lp - lum(xq, yq)) * in.invSigmaL;
                float e = -(ez + el) * px::kLog2e;
                if (in.sigmaN > 0.f) {
                    const float dot =
                        np[0] * nrm(0, xq, yq) + np[1] * nrm(1, xq, yq) + np[2] * nrm(2, xq, yq);
                    if (!(dot > 0.f)) continue;
                    e += in.sigmaN * px::fastLog2(std::min(std::max(dot, 1e-30f), 1.f));
                }
                wt = px::fastExp2(e);
            }
            sw += wt;
            for (int c = 0; c < 3; ++c) sc[c] += wt * col(c, xq, yq);
            m1 += wt * px::sanitize(sig.moments->at(0, xq, yq));
            m2 += wt * px::sanitizePositive(sig.moments->at(1, xq, yq), 1e32f);
        }
    }
    const float inv = 1.f / sw;  // sw >= 1 (centre)
    for (int c = 0; c < 3; ++c) c3[c] = sc[c] * inv;
    m1 *= inv;
    m2 *= inv;
    // Boost: few samples underestimate the variance (Falcor: 4 / historyLength).
    *v = std::max(0.f, m2 - m1 * m1) * (4.f / std::max(hl, 1.f));
}

/// Sanitised copies of columns [c0, c1) of one band's rows (and the 3 rows its taps reach above
/// and below): the 7x7 taps then load plain values instead of sanitising each of 49 reads. The
/// geometry's planes first, then each signal's six.
enum Plane { Z, NX, NY, NZ, kGeometryPlanes };
enum SignalPlane { L, R, G, B, M1, M2, kSignalPlanes };
constexpr int plane(int signal, SignalPlane p) {
    return kGeometryPlanes + kSignalPlanes * signal + p;
}

void prepareRow(const Inputs& in, std::span<const Signal> sig, int y, float* const* P, size_t o,
                int c0, int c1) {
    for (int c = 0; c < 3; ++c) {
        const float* n = in.normal->row(c, y);
        float* nd = P[NX + c] + o;
        for (int x = c0; x < c1; ++x) nd[x] = px::sanitizeNormal(n[x]);
    }
    const float* z = in.depth->row(0, y);
    float* pz = P[Z] + o;
    for (int x = c0; x < c1; ++x) pz[x] = px::sanitizeDepth(z[x]);
    for (int g = 0; g < int(sig.size()); ++g) {
        for (int c = 0; c < 3; ++c) {
            const float* src = sig[size_t(g)].color->row(c, y);
            float* dst = P[plane(g, SignalPlane(R + c))] + o;
            for (int x = c0; x < c1; ++x) dst[x] = px::sanitize(src[x]);
        }
        const float* m1 = sig[size_t(g)].moments->row(0, y);
        const float* m2 = sig[size_t(g)].moments->row(1, y);
        float *pm1 = P[plane(g, M1)] + o, *pm2 = P[plane(g, M2)] + o, *pl = P[plane(g, L)] + o;
        const float *r = P[plane(g, R)] + o, *gr = P[plane(g, G)] + o, *b = P[plane(g, B)] + o;
        for (int x = c0; x < c1; ++x) pm1[x] = px::sanitize(m1[x]);
        for (int x = c0; x < c1; ++x) pm2[x] = px::sanitizePositive(m2[x], 1e32f);
        for (int x = c0; x < c1; ++x) pl[x] = px::luminance(r[x], gr[x], b[x]);
    }
}

/// The same estimate for the lanes of one vector at (x0.., y), all taps inside the row range
/// [x0 - 3, x0 + lanes + 3), from the band's prepared planes (row y at (y - base) * width), for
/// S of the signals, sig[which[0]] .. sig[which[S - 1]], with the same weights (S = 2 only
/// without a luminance term). Signal g's lanes outside need[g] keep the pass-through values
/// already stored. One function of ~90 lines, a kernel: the centre's terms and the S signals'
/// accumulators stay in registers through the 49 taps, which a split would pass through memory.
template <int S>
void estimateBlock(const Inputs& in, std::span<const Signal> sig, const int* which, float* const* P,
                   int base, int x0, int y, const VF* hl, const MF* need) {
    const DF d;
    const DI di;
    const int w = in.w, h = in.h;
    const size_t stride = size_t(w);
    auto ld = [&](int plane, int dx, int yq) {
        return hn::LoadU(d, P[plane] + size_t(yq - base) * stride + size_t(x0 + dx));
    };
    const bool u = y > 0, dn = y + 1 < h;
    const bool lumTerm = S == 1 && in.invSigmaL > 0.f;
    const VF zp = ld(Z, 0, y), lp = lumTerm ? ld(plane(which[0], L), 0, y) : hn::Zero(d);
    const VF gx = simd::minAbsDiff(ld(Z, -1, y), zp, ld(Z, 1, y), true, true);
    const VF gy = simd::minAbsDiff(u ? ld(Z, 0, y - 1) : zp, zp, dn ? ld(Z, 0, y + 1) : zp, u, dn);
    const VF npx = ld(NX, 0, y), npy = ld(NY, 0, y), npz = ld(NZ, 0, y);
    const VI idp = in.ids ? hn::LoadU(di, in.ids + size_t(y) * stride + size_t(x0)) : hn::Zero(di);
    const VF sigmaZ = hn::Set(d, in.sigmaZ), sigmaN = hn::Set(d, in.sigmaN);
    const VF invSigmaL = hn::Set(d, in.invSigmaL), negLog2e = hn::Set(d, -px::kLog2e);
    const VF epsZ = hn::MulAdd(hn::Set(d, 1e-5f), zp, hn::Set(d, 1e-8f));
    const VF minDot = hn::Set(d, 1e-30f), one = hn::Set(d, 1.f), zero = hn::Zero(d);
    const int intPower = simd::integerExponent(in.sigmaN);
    VF sw = zero, sr[S], sg[S], sb[S], m1[S], m2[S];
    for (int g = 0; g < S; ++g) sr[g] = sg[g] = sb[g] = m1[g] = m2[g] = zero;
    for (int j = -kRadius; j <= kRadius; ++j) {
        const int yq = y + j;
        if (yq < 0 || yq >= h) continue;
        const VF gyj = hn::Mul(gy, hn::Set(d, float(j)));
        for (int i = -kRadius; i <= kRadius; ++i) {
            VF wt = one;
            if (i != 0 || j != 0) {
                // Same edge-stopping functions as A-Trous (SVGF eq. 3-4), luminance on the raw
                // difference (no variance yet: that is what we estimate). Without a luminance
                // term el is +0 and adds nothing: a pair leaves it out.
                const VF denom =
                    hn::MulAdd(sigmaZ, hn::Abs(hn::MulAdd(gx, hn::Set(d, float(i)), gyj)), epsZ);
                const VF ez = hn::Div(hn::Abs(hn::Sub(zp, ld(Z, i, yq))), denom);
                VF e = ez;
                if (lumTerm)
                    e = hn::Add(ez, hn::Mul(hn::Abs(hn::Sub(lp, ld(plane(which[0], L), i, yq))),
                                            invSigmaL));
                e = hn::Mul(e, negLog2e);
                VF wn = one;
                auto keep = hn::Eq(one, one);
                if (in.sigmaN > 0.f) {
                    const VF dot =
                        hn::MulAdd(npz, ld(NZ, i, yq),
                                   hn::MulAdd(npy, ld(NY, i, yq), hn::Mul(npx, ld(NX, i, yq))));
                    keep = hn::Gt(dot, zero);
                    if (intPower > 0)  // a whole exponent (the default 128): products only
                        wn = simd::powInt(hn::Min(hn::Max(dot, minDot), one), intPower);
                    else
                        e = hn::MulAdd(sigmaN, simd::fastLog2(hn::Min(hn::Max(dot, minDot), one)),
                                       e);
                }
                if (in.ids) {
                    const VI idq = hn::LoadU(di, in.ids + size_t(yq) * stride + size_t(x0 + i));
                    keep = hn::And(keep, hn::RebindMask(d, hn::Eq(idq, idp)));
                }
                wt = hn::IfThenElseZero(keep, hn::Mul(wn, simd::fastExp2(e)));
            }
            sw = hn::Add(sw, wt);
            for (int g = 0; g < S; ++g) {
                const int k = which[g];
                sr[g] = hn::MulAdd(wt, ld(plane(k, R), i, yq), sr[g]);
                sg[g] = hn::MulAdd(wt, ld(plane(k, G), i, yq), sg[g]);
                sb[g] = hn::MulAdd(wt, ld(plane(k, B), i, yq), sb[g]);
                m1[g] = hn::MulAdd(wt, ld(plane(k, M1), i, yq), m1[g]);
                m2[g] = hn::MulAdd(wt, ld(plane(k, M2), i, yq), m2[g]);
            }
        }
    }
    const VF inv = hn::Div(one, sw);  // sw >= 1 (centre)
    for (int g = 0; g < S; ++g) {
        const Signal& sg_ = sig[size_t(which[g])];
        const VF mean = hn::Mul(m1[g], inv);
        const VF var = hn::Max(zero, hn::NegMulAdd(mean, mean, hn::Mul(m2[g], inv)));
        // Boost: few samples underestimate the variance (Falcor: 4 / historyLength).
        const VF boost = hn::Div(hn::Set(d, 4.f), hn::Max(hl[which[g]], one));
        const VF acc[3] = {sr[g], sg[g], sb[g]};
        for (int c = 0; c < 3; ++c) {
            float* p = sg_.outC->row(c, y) + x0;
            hn::StoreU(hn::IfThenElse(need[which[g]], hn::Mul(acc[c], inv), hn::LoadU(d, p)), d, p);
        }
        if (sg_.outV) {
            float* p = sg_.outV->row(0, y) + x0;
            hn::StoreU(hn::IfThenElse(need[which[g]], hn::Mul(var, boost), hn::LoadU(d, p)), d, p);
        }
    }
}

/// A row's blocks of one vector (the vector path's pixels x = 3 + k n .. 3 + (k + 1) n, and a
/// last one ending at w - 3). Which pixels take which path depends only on the width, never on
/// the thread count or the banding.
struct Blocks {
    int w, n, whole, count, scalarFrom;
    explicit Blocks(int width) : w(width), n(int(hn::Lanes(DF()))) {
        whole = w >= 2 * kRadius + n ? (w - 2 * kRadius) / n : 0;
        // A last block ends at w - kRadius where whole blocks leave a gap (it overlaps the one
        // before it, whose pixels it computes again to the same values): only the kRadius
        // columns at either border, whose taps leave the image, take the plain scalar code.
        const bool tail = whole > 0 && kRadius + whole * n < w - kRadius;
        count = whole + int(tail);
        scalarFrom = tail ? w - kRadius : kRadius + whole * n;
    }
    int x(int k) const { return k < whole ? kRadius + k * n : w - kRadius - n; }
};

/// Rows [y0, y1) of each signal: the temporal estimate passed through everywhere (sanitised);
/// need[k] set where block k holds a pixel with a short history. Returns whether a border
/// pixel (the scalar code's) has one; anyBlock: whether a block has.
bool passThrough(std::span<const Signal> sig, const Blocks& b, int y0, int y1,
                 std::vector<uint8_t>& need, bool& anyBlock) {
    const DF d;
    const int w = b.w;
    bool anyScalar = false;
    for (const Signal& s : sig) {
        const VF minH = hn::Set(d, s.minHist);
        for (int y = y0; y < y1; ++y) {
            float* oc[3] = {s.outC->row(0, y), s.outC->row(1, y), s.outC->row(2, y)};
            const float* hrow = s.hist->row(0, y);
            for (int c = 0; c < 3; ++c) {
                const float* src = s.color->row(c, y);
                for (int x = 0; x < w; ++x) oc[c][x] = px::sanitize(src[x]);
            }
            if (s.outV) {
                const float* src = s.var->row(0, y);
                float* ov = s.outV->row(0, y);
                for (int x = 0; x < w; ++x) ov[x] = px::sanitizePositive(src[x], 1e32f);
            }
            auto isShort = [&](int x) {
                return !(px::sanitizePositive(hrow[x], 1e6f) >= s.minHist);
            };
            for (int x = 0; x < std::min(kRadius, w); ++x) anyScalar |= isShort(x);
            for (int x = b.scalarFrom; x < w; ++x) anyScalar |= isShort(x);
            for (int k = 0; k < b.count; ++k) {
                const VF hl = simd::sanitizePositive(hn::LoadU(d, hrow + b.x(k)), 1e6f);
                const bool sh = !hn::AllFalse(d, hn::Lt(hl, minH));
                need[size_t(k)] |= uint8_t(sh);
                anyBlock |= sh;
            }
        }
    }
    return anyScalar;
}

/// The border pixels of rows [y0, y1) with a short history, reading the inputs directly.
void estimateBorders(const Inputs& in, std::span<const Signal> sig, const Blocks& b, int y0,
                     int y1) {
    const int w = b.w;
    for (const Signal& s : sig)
        for (int y = y0; y < y1; ++y) {
            float* oc[3] = {s.outC->row(0, y), s.outC->row(1, y), s.outC->row(2, y)};
            float* ov = s.outV ? s.outV->row(0, y) : nullptr;
            const float* hrow = s.hist->row(0, y);
            auto scalarAt = [&](int x) {
                const float hl = px::sanitizePositive(hrow[x], 1e6f);
                if (hl >= s.minHist) return;
                float c3[3], v;
                estimatePixel(in, s, x, y, hl, c3, &v);
                for (int c = 0; c < 3; ++c) oc[c][x] = c3[c];
                if (ov) ov[x] = v;
            };
            for (int x = 0; x < std::min(kRadius, w); ++x) scalarAt(x);
            for (int x = std::max(b.scalarFrom, kRadius); x < w; ++x) scalarAt(x);
        }
}

/// Prepares the needed blocks' columns (with the taps' reach of 3 on either side) of rows
/// [base, p1) into P, runs of needed blocks at once.
void prepareBlocks(const Inputs& in, std::span<const Signal> sig, const Blocks& b,
                   const std::vector<uint8_t>& need, float* const* P, int base, int p1) {
    for (int k0 = 0; k0 < b.count;) {
        if (!need[size_t(k0)]) {
            ++k0;
            continue;
        }
        int k1 = k0 + 1;
        while (k1 < b.count && need[size_t(k1)]) ++k1;
        for (int y = base; y < p1; ++y)
            prepareRow(in, sig, y, P, size_t(y - base) * size_t(b.w), b.x(k0) - kRadius,
                       b.x(k1 - 1) + b.n + kRadius);
        k0 = k1;
    }
}

/// The needed blocks of rows [y0, y1), from the prepared planes P (row `base` first).
void estimateBlocks(const Inputs& in, std::span<const Signal> sig, const Blocks& b,
                    const std::vector<uint8_t>& need, float* const* P, int base, int y0, int y1) {
    const DF d;
    const int S = int(sig.size());
    for (int y = y0; y < y1; ++y)
        for (int k = 0; k < b.count; ++k) {
            if (!need[size_t(k)]) continue;
            const int x = b.x(k);
            VF hl[2];
            MF needLanes[2];
            int which[2], count = 0;  // the signals with a short pixel here
            for (int g = 0; g < S; ++g) {
                const Signal& s = sig[size_t(g)];
                hl[g] = simd::sanitizePositive(hn::LoadU(d, s.hist->row(0, y) + x), 1e6f);
                needLanes[g] = hn::Lt(hl[g], hn::Set(d, s.minHist));
                if (!hn::AllFalse(d, needLanes[g])) which[count++] = g;
            }
            // Both signals weighed at once only where both need it: a pair's short pixels
            // overlap only in part (anti-lag shortens each chain's history on its own).
            if (count == 2)
                estimateBlock<2>(in, sig, which, P, base, x, y, hl, needLanes);
            else if (count == 1)
                estimateBlock<1>(in, sig, which, P, base, x, y, hl, needLanes);
        }
}

/// The fast path (everything but `exact`) for this target, for one signal or a pair with the
/// same weights (VarianceEstimationPass::executeFused): each pixel's estimate is the one the
/// signal would get alone, to the bit.
void estimate(FrameContext& ctx, const Inputs& in, std::span<const Signal> sig,
              std::span<float* const> idle) {
    ScratchArena arena(idle, ctx.extent.pixels());  // scratch from idle planes where they suffice
    const int w = in.w, S = int(sig.size());
    // Bands of rows, each with private scratch for its prepared rows (ScratchPool). Only the
    // columns of blocks holding a pixel with a short history (in any signal) are prepared, which
    // in steady state is a few percent (disocclusions), not every band as soon as one pixel of
    // it is short (a pan disoccludes a column at the image's edge in every band).
    constexpr int kBand = 32;
    const int bands = (in.h + kBand - 1) / kBand;
    const size_t bandPixels = size_t(std::min(in.h, kBand + 2 * kRadius)) * size_t(w);
    const Blocks blocks(w);
    ctx.parallel->forRange(
        0, bands,
        [&](int i0, int i1) {
            thread_local std::vector<uint8_t> need;  // per block: prepare and estimate
            need.resize(static_cast<size_t>(blocks.count));
            for (int i = i0; i < i1; ++i) {
                const int y0 = i * kBand, y1 = std::min(in.h, y0 + kBand);
                std::fill(need.begin(), need.end(), uint8_t(0));
                bool anyBlock = false;
                if (passThrough(sig, blocks, y0, y1, need, anyBlock))
                    estimateBorders(in, sig, blocks, y0, y1);
                if (!anyBlock) continue;
                // The vector path on the band's rows, its halo prepared too.
                const int base = std::max(0, y0 - kRadius), p1 = std::min(in.h, y1 + kRadius);
                auto lease = arena.acquire(size_t(kGeometryPlanes + kSignalPlanes * S), bandPixels);
                float* P[kGeometryPlanes + 2 * kSignalPlanes];
                for (int k = 0; k < kGeometryPlanes + kSignalPlanes * S; ++k)
                    P[k] = lease[size_t(k)];
                prepareBlocks(in, sig, blocks, need, P, base, p1);
                estimateBlocks(in, sig, blocks, need, P, base, y0, y1);
            }
        },
        1);
}

}  // namespace
}  // namespace kestrel::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace kestrel {
namespace {
HWY_EXPORT(estimate);
}  // namespace
}  // namespace kestrel

using namespace kestrel;

VarianceEstimationPass::Declaration::Declaration()
    : kestrel::Declaration<Params>(
          "VarianceEstimation",
          "Spatial variance estimate where the history is short: 7x7 cross-bilateral moments"
          " (depth, normal, luminance weights), variance boosted by 4 / historyLength; colour"
          " filtered with the same weights. Elsewhere colour and variance pass through.") {
    color = input("color", Format::Float3, "temporally accumulated illumination");
    moments = input("moments", Format::Float2, "accumulated luminance moments (l, l^2)");
    historyLength = input("historyLength", Format::Float, "history length per pixel");
    variance = input("variance", Format::Float, "temporal variance");
    depth = input("depth", Format::Float, "linear view depth");
    normal = input("normal", Format::Float3, "world-space normal");
    objectId =
        optionalInput("objectId", Format::Int32, "object id: taps on another object get weight 0");
    colorOut =
        output("color", Format::Float3, "illumination (filtered where the history is short)");
    varianceOut = output("variance", Format::Float, "luminance variance");
    fuseOn({&depth, &normal, &objectId});
    paramDecimal("sigmaZ", &Params::sigmaZ, 0.0, 1e6,
                 "depth weight tolerance in units of the depth slope");
    paramDecimal("sigmaN", &Params::sigmaN, 0.0, 1e4, "normal weight exponent");
    paramDecimal("sigmaL", &Params::sigmaL, 0.0, 1e6,
                 "luminance weight exp(-|l_p - l_q| / sigmaL) in absolute luminance (Falcor's"
                 " phiColor, 10; values below 1e-6 count as 1e-6); 0: none. Off by default: in "
                 "absolute units it depends on the"
                 " render's exposure (svgf.json on blender-street 1000x brighter: -2.5 dB with"
                 " 10, blender-street-defaults -8 dB), at scale 1 it measured -0.17 to +0.04 dB");
    paramDecimal("minHistoryLength", &Params::minHistoryLength, 0.0, 1e6,
                 "history length below which the spatial estimate is used");
    param("exact", &Params::exact,
          "run the plain scalar path (libm exp/pow, no SIMD) to measure what the fast"
          " path's approximations cost in error; several times slower");
}

const VarianceEstimationPass::Declaration& VarianceEstimationPass::declaration() {
    static const Declaration d;
    return d;
}

namespace {
const ImageView* boundInput(PassIO& io, const InputPort& p) {
    return io.has(p) ? &io.input(p) : nullptr;
}

Inputs sharedInputs(const FrameContext& ctx, PassIO& io, const VarianceEstimationPass::Params& p) {
    const VarianceEstimationPass::Declaration& d = VarianceEstimationPass::declaration();
    const ImageView* ids = boundInput(io, d.objectId);
    return {ctx.extent.width,
            ctx.extent.height,
            &io.input(d.depth),
            &io.input(d.normal),
            ids ? ids->ints() : nullptr,
            p.sigmaZ,
            p.sigmaN,
            p.sigmaL > 0.f ? 1.f / std::max(p.sigmaL, reference::kMinSigmaL) : 0.f};
}

Signal signalOf(PassIO& io, float minHist) {
    const VarianceEstimationPass::Declaration& d = VarianceEstimationPass::declaration();
    return {&io.input(d.color),
            &io.input(d.moments),
            &io.input(d.historyLength),
            &io.input(d.variance),
            &io.output(d.colorOut),
            io.has(d.varianceOut) ? &io.output(d.varianceOut) : nullptr,
            minHist};
}

/// Whether two passes read the same geometry (a pair then weighs each tap once for both).
bool sameGeometry(PassIO& a, PassIO& b) {
    const VarianceEstimationPass::Declaration& d = VarianceEstimationPass::declaration();
    const ImageView *ia = boundInput(a, d.objectId), *ib = boundInput(b, d.objectId);
    return a.input(d.depth).planes == b.input(d.depth).planes &&
           a.input(d.normal).planes == b.input(d.normal).planes &&
           (ia == nullptr) == (ib == nullptr) && (!ia || ia->planes == ib->planes);
}
}  // namespace

std::string VarianceEstimationPass::fusionKey() const {
    // A pair shares each tap's weight, which without a luminance term is the geometry's alone.
    if (p_.exact || p_.sigmaL > 0.f) return {};
    char key[96];
    std::snprintf(key, sizeof key, "sigmaZ=%a sigmaN=%a", double(p_.sigmaZ), double(p_.sigmaN));
    return key;
}

void VarianceEstimationPass::executeFused(FrameContext& ctx, std::span<Pass* const> passes,
                                          std::span<PassIO* const> ios) {
    // Pairs weigh each tap once for both signals (the split's diffuse and specular chains);
    // an odd one out runs alone.
    size_t i = 0;
    for (; i + 1 < ios.size(); i += 2) {
        PassIO &a = *ios[i], &b = *ios[i + 1];
        if (!sameGeometry(a, b)) {
            passes[i]->execute(ctx, a);
            passes[i + 1]->execute(ctx, b);
            continue;
        }
        const Inputs in = sharedInputs(ctx, a, p_);
        auto minHist = [&](size_t k) {
            return static_cast<const VarianceEstimationPass&>(*passes[k]).p_.minHistoryLength;
        };
        const Signal sig[2] = {signalOf(a, minHist(i)), signalOf(b, minHist(i + 1))};
        HWY_DYNAMIC_DISPATCH(estimate)(ctx, in, std::span<const Signal>(sig), a.idlePlanes());
    }
    if (i < ios.size()) passes[i]->execute(ctx, *ios[i]);
}

void VarianceEstimationPass::execute(FrameContext& ctx, PassIO& io) {
    const Inputs in = sharedInputs(ctx, io, p_);
    const Signal sig = signalOf(io, p_.minHistoryLength);
    if (p_.exact) {
        const reference::VarianceInputs ref{sig.color,
                                            sig.moments,
                                            sig.hist,
                                            sig.var,
                                            in.depth,
                                            in.normal,
                                            boundInput(io, declaration().objectId),
                                            p_.sigmaZ,
                                            p_.sigmaN,
                                            p_.sigmaL,
                                            p_.minHistoryLength};
        ctx.parallelRows(in.h, [&](int y0, int y1) {
            reference::varianceEstimation(ref, *sig.outC, sig.outV, y0, y1);
        });
        return;
    }
    HWY_DYNAMIC_DISPATCH(estimate)(ctx, in, std::span<const Signal>(&sig, 1), io.idlePlanes());
}
#endif  // HWY_ONCE
