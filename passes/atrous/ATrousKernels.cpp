// Compiled once per SIMD target (hwy/foreach_target.h re-includes this file for each one); the
// per-target kernels live in kestrel::N_<TARGET>, everything else in the HWY_ONCE part at the
// end, which picks the best target of the running CPU (HWY_DYNAMIC_DISPATCH).
#include "ATrousPass.h"

#include <kestrel/PixelMath.h>
#include <kestrel/Scratch.h>

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <numeric>
#include <vector>

#include "ATrousReference.h"

#ifndef KESTREL_ATROUS_BINDINGS_
#define KESTREL_ATROUS_BINDINGS_
namespace {
/// The pass's bound images, shared by the fast (per-target) and the exact path.
struct Bindings {
    explicit Bindings(kestrel::PassIO& io)
        : color(io.input("color")),
          depth(io.input("depth")),
          normal(io.input("normal")),
          var(io.hasInput("variance") ? &io.input("variance") : nullptr),
          idView(io.hasInput("objectId") ? &io.input("objectId") : nullptr),
          ids(idView ? idView->ints() : nullptr),
          outColor(io.output("color")),
          outVar(var && io.hasOutput("variance") ? &io.output("variance") : nullptr) {}
    const kestrel::ImageView &color, &depth, &normal;
    const kestrel::ImageView *var, *idView;
    const int32_t* ids;
    const kestrel::ImageView& outColor;
    const kestrel::ImageView* outVar;
};
}  // namespace
#endif

#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "ATrousPass.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep
// After foreach_target.h: once per target.
#include <hwy/highway.h>
#include <kestrel/SimdMath.h>

HWY_BEFORE_NAMESPACE();
namespace kestrel::HWY_NAMESPACE {
namespace {

namespace hn = hwy::HWY_NAMESPACE;
constexpr float kH[5] = {1.f / 16.f, 1.f / 4.f, 3.f / 8.f, 1.f / 4.f, 1.f / 16.f};
constexpr float kEpsL = 1e-10f;    // SVGF eq. 5 epsilon (Falcor uses 1e-10 too)
constexpr float kEpsZRel = 1e-5f;  // depth tolerance floor relative to z: float depth noise
constexpr float kEpsZAbs = 1e-8f;
constexpr float kMinDot = 1e-30f;
constexpr float kZeroWeight = -1e4f;  // log2 weight penalty: fastExp2 returns exactly 0
constexpr float kLn2 = 0.693147180559945f;
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

/// The filter for K consecutive vectors of pixels (x0 .. x0 + K lanes) of row y. The centres'
/// terms and the accumulators stay in registers while the taps stream by, and independent
/// dependency chains (exp2, the normal's power) overlap in the pipeline. Plane rows are `pitch`
/// apart, row `base` first. kEdge blocks (near the left or right border, K = 1) give taps
/// outside the row weight exactly 0, as the image border requires, and store only the lanes
/// inside the row. With kMaskedEdges their loads are masked (masked-off lanes load 0), so they
/// never read past a row's ends, whether the planes are read in place or copied; elsewhere
/// they read into the copied planes' zeroed margins. Returns whether the
/// centre pixels' inputs are clean: sanitising them (pass 1 below) would change nothing (the
/// tests are exactly the identity conditions of px::sanitize, sanitizeNormal, sanitizeDepth
/// and sanitizePositive).
template <int K, int S, int kSquarings, bool kEdge, bool kId, bool kNormal, bool kVar>
bool filterBlocks(int x0, int y, int width, size_t pitch, int height, const ATrousPass::Settings& s,
                  float* const* P, int base, const int32_t* ids, float* const (*oc)[3],
                  float* const* ov, bool checkVar) {
    static_assert(!kEdge || K == 1);
    static_assert(S == 1 || S == 2);
    const DF d;
    const DI di;
    const size_t n = hn::Lanes(d);
    const ptrdiff_t o = ptrdiff_t(y - base) * ptrdiff_t(pitch) + x0;
    using MF = hn::Mask<DF>;
    constexpr bool kMasked = kEdge && kMaskedEdges;
    auto load = [&](const float* plane, ptrdiff_t q, MF m) HWY_ATTR {
        if constexpr (kMasked)
            return hn::MaskedLoad(m, d, plane + q);
        else
            return hn::LoadU(d, plane + q);
    };
    auto loadId = [&](ptrdiff_t q, MF m) HWY_ATTR {
        if constexpr (kMasked)
            return hn::MaskedLoad(hn::RebindMask(di, m), di, ids + q);
        else
            return hn::LoadU(di, ids + q);
    };
    // The centre lanes inside the row (all but in the row's last, partial vector).
    const MF centreIn = hn::FirstN(d, size_t(std::min<int>(int(n), width - x0)));
    const VF kc = hn::Set(d, kH[2] * kH[2]);
    // Pre-scaled so a tap's exponent is one multiply-add: e = |dz| / denomZ' + |dl| * nInvL,
    // with denomZ' = -ln2 (sigma_z |grad z . d| + eps) and nInvL = -log2(e) / (sigma_l ...).
    // The geometry's terms are shared by the signals; luminance and accumulators are per signal.
    VF cz[K], cgx[K], cgy[K], cnx[K], cny[K], cnz[K], epsZ[K], qz[K];
    VF cl[S][K], nInvL[S][K];
    VI cid[K];
    VF aw[S][K], ar[S][K], ag[S][K], ab[S][K], av[S][K];
    MF clean = hn::FirstN(d, n);
    // Clean: the sanitiser (the vector forms of pass 1's) returns the value itself; NaN never
    // compares equal, and +-0 are returned as they are.
    auto same = [](VF v, VF sanitised) HWY_ATTR { return hn::Eq(sanitised, v); };
#pragma GCC unroll 4
    for (int k = 0; k < K; ++k) {
        const ptrdiff_t ok = o + ptrdiff_t(k * n);
        cz[k] = load(P[Z], ok, centreIn);
        cgx[k] = load(P[GX], ok, centreIn);
        cgy[k] = load(P[GY], ok, centreIn);
        cnx[k] = load(P[NX], ok, centreIn);
        cny[k] = load(P[NY], ok, centreIn);
        cnz[k] = load(P[NZ], ok, centreIn);
        cid[k] = kId ? loadId(ok, centreIn) : hn::Zero(di);
        // Quantised depth (relative step r = depthPrecision, 0 for float) misestimates the
        // slope by up to r z per pixel and each depth by r z: the tolerance grows by both
        // (r z per pixel of tap distance, pre-scaled like sigmaZ, and r z in epsZ).
        epsZ[k] = hn::Mul(
            hn::MulAdd(hn::Set(d, kEpsZRel + s.depthPrecision), cz[k], hn::Set(d, kEpsZAbs)),
            hn::Set(d, -kLn2));
        qz[k] = hn::Mul(hn::Set(d, -kLn2 * s.sigmaZ * s.depthPrecision), cz[k]);
        MF c = same(cz[k], simd::sanitizeDepth(cz[k]));
        if constexpr (kNormal)
            c = hn::And(c, hn::And(hn::And(same(cnx[k], simd::sanitizeNormal(cnx[k])),
                                           same(cny[k], simd::sanitizeNormal(cny[k]))),
                                   same(cnz[k], simd::sanitizeNormal(cnz[k]))));
#pragma GCC unroll 2
        for (int g = 0; g < S; ++g) {
            cl[g][k] = load(P[kLum[g]], ok, centreIn);
            nInvL[g][k] = hn::Mul(load(P[kInvL[g]], ok, centreIn), hn::Set(d, -px::kLog2e));
            aw[g][k] = kc;
            const VF r = load(P[kRgb[g][0]], ok, centreIn), gr = load(P[kRgb[g][1]], ok, centreIn),
                     b = load(P[kRgb[g][2]], ok, centreIn);
            ar[g][k] = hn::Mul(kc, r);
            ag[g][k] = hn::Mul(kc, gr);
            ab[g][k] = hn::Mul(kc, b);
            // The variance is checked wherever it is bound: the luminance weight's prefilter
            // reads it even when the propagated variance is not wanted (checkVar without kVar).
            const bool withVar = kVar || checkVar;
            const VF v = withVar ? load(P[kVarPlane[g]], ok, centreIn) : hn::Zero(d);
            av[g][k] = kVar ? hn::Mul(hn::Mul(kc, kc), v) : hn::Zero(d);
            c = hn::And(c,
                        hn::And(hn::And(same(r, simd::sanitize(r)), same(gr, simd::sanitize(gr))),
                                same(b, simd::sanitize(b))));
            if (withVar) c = hn::And(c, same(v, simd::sanitizePositive(v, kMaxVariance)));
        }
        clean = hn::And(clean, c);
    }
    clean = hn::Or(clean, hn::Not(centreIn));  // lanes outside the row do not count
    const VF sigmaZ = hn::Set(d, -kLn2 * s.sigmaZ), sigmaN = hn::Set(d, s.sigmaN);
    const VF zeroWeight = hn::Set(d, kZeroWeight), two = hn::Set(d, 2.f);
    const VF minDot = hn::Set(d, kMinDot), one = hn::Set(d, 1.f), zero = hn::Zero(d);
    const int intPower = simd::integerExponent(s.sigmaN);
    // Taps q[0..T) of vector k, given their shared depth reciprocal and kernel weight. With
    // T = 2 the two taps' statements alternate, so each step of one tap's long dependency
    // chain (dot, seven squarings, exp2) has the other's beside it to fill the pipeline.
    const VI column = hn::Iota(di, x0);  // kEdge: each lane's x
    const VI firstColumn = hn::Set(di, -1), pastLast = hn::Set(di, width);
    auto taps = [&](auto count, int k, const ptrdiff_t* q, const int* dxs, VF rz, VF kh) HWY_ATTR {
        constexpr int T = decltype(count)::value;
        VF e[S][T], w[T];
        MF in[T];  // kEdge: the lanes whose tap is inside the row
#pragma GCC unroll 2
        for (int t = 0; t < T; ++t) {
            if constexpr (kEdge) {
                const VI xq = hn::Add(column, hn::Set(di, dxs[t]));
                in[t] = hn::RebindMask(d, hn::And(hn::Gt(xq, firstColumn), hn::Lt(xq, pastLast)));
            } else {
                in[t] = hn::FirstN(d, n);
            }
        }
#pragma GCC unroll 2
        for (int t = 0; t < T; ++t) {
            // SVGF eq. 3 (depth) and eq. 5 (luminance, 1 / denominator precomputed).
            const VF adz = hn::Abs(hn::Sub(cz[k], load(P[Z], q[t], in[t])));
#pragma GCC unroll 2
            for (int g = 0; g < S; ++g) {
                const VF adl = hn::Abs(hn::Sub(cl[g][k], load(P[kLum[g]], q[t], in[t])));
                e[g][t] = hn::MulAdd(adz, rz, hn::Mul(adl, nInvL[g][k]));
            }
            w[t] = kh;
        }
        if constexpr (kNormal) {  // SVGF eq. 4: max(0, n_p . n_q)^sigma_n
            VF dot[T];
#pragma GCC unroll 2
            for (int t = 0; t < T; ++t)
                dot[t] = hn::MulAdd(cnz[k], load(P[NZ], q[t], in[t]),
                                    hn::MulAdd(cny[k], load(P[NY], q[t], in[t]),
                                               hn::Mul(cnx[k], load(P[NX], q[t], in[t]))));
            if constexpr (kSquarings > 0) {
                // sigma_n = 2^kSquarings (the default 128): products only.
                VF wn[T];
#pragma GCC unroll 2
                for (int t = 0; t < T; ++t) wn[t] = hn::Min(hn::Max(dot[t], zero), one);
#pragma GCC unroll 16
                for (int m = 0; m < kSquarings; ++m)
#pragma GCC unroll 2
                    for (int t = 0; t < T; ++t) wn[t] = hn::Mul(wn[t], wn[t]);
#pragma GCC unroll 2
                for (int t = 0; t < T; ++t) w[t] = hn::Mul(w[t], wn[t]);
            } else {
#pragma GCC unroll 2
                for (int t = 0; t < T; ++t) {
                    if (intPower > 0) {  // another whole exponent
                        w[t] = hn::Mul(w[t],
                                       simd::powInt(hn::Min(hn::Max(dot[t], zero), one), intPower));
                    } else {
                        const VF logDot = simd::fastLog2(hn::Min(hn::Max(dot[t], minDot), one));
                        const VF facing = hn::IfThenZeroElse(hn::Gt(dot[t], zero), zeroWeight);
#pragma GCC unroll 2
                        for (int g = 0; g < S; ++g)
                            e[g][t] = hn::Add(hn::MulAdd(sigmaN, logDot, e[g][t]), facing);
                    }
                }
            }
        }
        MF keep[T];  // a tap on another object, or outside the row, has weight exactly 0
#pragma GCC unroll 2
        for (int t = 0; t < T; ++t) {
            keep[t] = in[t];
            if constexpr (kId)
                keep[t] = hn::And(keep[t], hn::RebindMask(d, hn::Eq(cid[k], loadId(q[t], in[t]))));
        }
#pragma GCC unroll 2
        for (int g = 0; g < S; ++g) {
            const int* rgb = kRgb[g];
#pragma GCC unroll 2
            for (int t = 0; t < T; ++t) {
                VF wg = hn::Mul(w[t], simd::fastExp2(e[g][t]));
                if constexpr (kId || kEdge) wg = hn::IfThenElseZero(keep[t], wg);
                aw[g][k] = hn::Add(aw[g][k], wg);
                ar[g][k] = hn::MulAdd(wg, load(P[rgb[0]], q[t], in[t]), ar[g][k]);
                ag[g][k] = hn::MulAdd(wg, load(P[rgb[1]], q[t], in[t]), ag[g][k]);
                ab[g][k] = hn::MulAdd(wg, load(P[rgb[2]], q[t], in[t]), ab[g][k]);
                if constexpr (kVar)
                    av[g][k] =
                        hn::MulAdd(hn::Mul(wg, wg), load(P[kVarPlane[g]], q[t], in[t]), av[g][k]);
            }
        }
    };
    // The 24 taps as 12 point-symmetric pairs q = p + d and q' = p - d: both have the same
    // kernel weight and the same depth denominator sigma_z |grad z(p) . d| + eps, so the
    // reciprocal is computed once per pair, and the two taps are independent work that
    // overlaps in the pipeline (one tap alone is a long dependency chain: dot, seven
    // squarings, exp2).
    const ptrdiff_t rowStride = ptrdiff_t(pitch);
    const ptrdiff_t centre = o;
    for (int j = 0; j <= 2; ++j) {
        const int dy = (j - 2) * s.step;
        const bool upIn = y + dy >= 0, downIn = y - dy < height;  // dy <= 0
        if (!upIn && !downIn) continue;  // taps outside the image are skipped
        const VF fdy = hn::Set(d, float(dy));
        VF gy[K];
#pragma GCC unroll 4
        for (int k = 0; k < K; ++k) gy[k] = hn::Mul(cgy[k], fdy);
        for (int i = 0; i < (j == 2 ? 2 : 5); ++i) {
            const int dx = (i - 2) * s.step;
            const VF fdx = hn::Set(d, float(dx));
            const VF tapDistance = hn::Set(d, float(std::abs(dx) + std::abs(dy)));
            const VF kh = hn::Set(d, kH[i] * kH[j]);
            const ptrdiff_t off = ptrdiff_t(dy) * rowStride + dx;
#pragma GCC unroll 4
            for (int k = 0; k < K; ++k) {
                // The depth reciprocal is the hardware estimate refined by one Newton step
                // (relative error ~1e-7; a division is exact to 6e-8 and costs several times
                // as much).
                const VF denomZ = hn::MulAdd(sigmaZ, hn::Abs(hn::MulAdd(cgx[k], fdx, gy[k])),
                                             hn::MulAdd(qz[k], tapDistance, epsZ[k]));
                const VF r0 = hn::ApproximateReciprocal(denomZ);
                const VF rz = hn::Mul(r0, hn::NegMulAdd(denomZ, r0, two));
                const ptrdiff_t ck = centre + ptrdiff_t(k * n);
                const ptrdiff_t q[2] = {ck + off, ck - off};
                const int dxs[2] = {dx, -dx};
                if (upIn && downIn)
                    taps(std::integral_constant<int, 2>{}, k, q, dxs, rz, kh);
                else if (upIn)
                    taps(std::integral_constant<int, 1>{}, k, q, dxs, rz, kh);
                else
                    taps(std::integral_constant<int, 1>{}, k, q + 1, dxs + 1, rz, kh);
            }
        }
    }
#pragma GCC unroll 2
    for (int g = 0; g < S; ++g) {
#pragma GCC unroll 4
        for (int k = 0; k < K; ++k) {
            const size_t xk = size_t(x0) + size_t(k) * n;
            const VF inv = hn::Div(one, aw[g][k]);  // aw >= kc > 0
            // SVGF eq. 2: Var = sum(w^2 Var_q) / (sum w)^2
            const VF out[4] = {hn::Mul(ar[g][k], inv), hn::Mul(ag[g][k], inv),
                               hn::Mul(ab[g][k], inv), hn::Mul(av[g][k], hn::Mul(inv, inv))};
            float* const dst[4] = {oc[g][0], oc[g][1], oc[g][2], ov[g]};
            const int planes = ov[g] ? 4 : 3;
            if (!kEdge || x0 + int(n) <= width) {
                for (int c = 0; c < planes; ++c) hn::StoreU(out[c], d, dst[c] + xk);
            } else {  // the row's last, partial vector: only the lanes inside the row
                HWY_ALIGN float lanes[HWY_MAX_BYTES / sizeof(float)];
                for (int c = 0; c < planes; ++c) {
                    hn::Store(out[c], d, lanes);
                    std::copy_n(lanes, width - x0, dst[c] + xk);
                }
            }
        }
    }
    return hn::AllTrue(d, clean);
}

/// Rows [y0, y1): whole vectors where every tap is inside the row, edge blocks (masked taps,
/// partial last vector) near the borders. Which pixels take which path depends only on the
/// width and step, never on the banding or thread count.
template <int S, int kSquarings, bool kId, bool kNormal, bool kVar>
void filterRange(int y0, int y1, int width, size_t pitch, int height, const ATrousPass::Settings& s,
                 float* const* P, int base, const int32_t* ids, const Bindings* const* b,
                 uint8_t* rowClean, bool checkVar) {
    // Two vectors per block: on AVX-512 (1080p, 1 thread, min of 7) 52.8-55.2 ms at step 1
    // against 54.5-56.9 ms for one vector, equal at step 16. A pair of signals keeps twice the
    // accumulators in registers: one vector (two spill: 1080p step 1, 2 threads, 35.6 against
    // 27.0 ms per pair).
    constexpr int K = S == 1 ? 2 : 1;
    const int n = int(hn::Lanes(DF()));
    const int reach = 2 * s.step;
    for (int y = y0; y < y1; ++y) {
        float* oc[S][3];
        float* ov[S];
        for (int g = 0; g < S; ++g) {
            for (int c = 0; c < 3; ++c) oc[g][c] = b[g]->outColor.row(c, y);
            ov[g] = b[g]->outVar ? b[g]->outVar->row(0, y) : nullptr;
        }
        bool clean = true;
        auto block = [&](auto k, auto edge, int x) {
            clean &=
                filterBlocks<decltype(k)::value, S, kSquarings, decltype(edge)::value, kId, kNormal,
                             kVar>(x, y, width, pitch, height, s, P, base, ids, oc, ov, checkVar);
        };
        using One = std::integral_constant<int, 1>;
        using Two = std::integral_constant<int, K>;
        using Edge = std::true_type;
        using Inside = std::false_type;
        int x = 0;
        for (; x < width && x < reach; x += n) block(One{}, Edge{}, x);
        for (; x + K * n + reach <= width; x += K * n) block(Two{}, Inside{}, x);
        for (; x + n + reach <= width; x += n) block(One{}, Inside{}, x);
        for (; x < width; x += n) block(One{}, Edge{}, x);
        rowClean[y] = clean;
    }
}

/// The fast path (everything but `exact`) for this target: one signal, or a fused pair
/// (`signals` = 2) sharing the first's geometry and geometric settings; each signal's own
/// settings give its luminance weight (sigmaL, sigmaColor). Band scratch comes from the step's
/// idle planes where they suffice (ScratchArena).
void filterFast(FrameContext& ctx, const Bindings* const* b, int signals,
                const ATrousPass::Settings* settings, std::span<float* const> idle) {
    ScratchArena arena(idle, ctx.extent.pixels());
    const int width = ctx.extent.width, height = ctx.extent.height;
    const ImageView &depth = b[0]->depth, &normal = b[0]->normal;
    const int32_t* ids = b[0]->ids;
    const bool withVar = std::any_of(b, b + signals, [](const Bindings* g) { return g->outVar; });
    const bool checkVar = b[0]->var != nullptr;
    // The image is filtered in bands of rows, each with private scratch planes covering the
    // band and the rows its taps reach (2 step above and below): scratch then scales with the
    // band, not the frame (at 1080p and step 16, 13 planes of 128 rows, ~13 MB per thread, and
    // 4 planes when the band reads its inputs in place, instead of ~108 MB), at the cost of
    // recomputing the halo rows' terms. Every value depends only on its pixel's neighbourhood,
    // so results do not depend on the banding. Copied bands' rows are `pitch` apart, each
    // followed by a margin of the reach plus one vector (which is also the next row's left
    // margin; the first row has one before it), zeroed where the edge vectors' loads are not
    // masked (!kMaskedEdges), so that they may read past a row's ends.
    // Bands of 64 rows (twice the reach from step 16 on): the halo is then a quarter of the
    // band at step 4 (it was half with 32-row bands: 57-62 against 66-70 ms, 1 thread), and the
    // largest scratch, step 16's 64 + 2 x 32 rows, stays the same.
    const ATrousPass::Settings s = settings[0];
    const int reach = 2 * s.step;
    const int band = std::min(height, std::max(64, 2 * reach));
    const int bands = (height + band - 1) / band;
    const int maxRows = std::min(height, band + 2 * reach);
    const size_t margin = size_t(reach) + hn::Lanes(DF());
    const size_t pitch = size_t(width) + margin;
    const size_t bandPixels = margin + size_t(maxRows) * pitch;
    const bool useNormal = s.sigmaN > 0.f;
    // Inputs are nearly always clean (the previous iteration's output, the loader's geometry),
    // so every band first reads them in place, without copying nine planes into scratch
    // (1080p, 1 thread, min of 5, three alternating rounds: step 1 51-52 -> 44-45 ms, step 16
    // 54-56 -> 44-48; 2 threads 27-32 -> 23-33, noisier), while the kernel checks each centre
    // pixel's inputs (filterBlocks). A band whose rows, its halo included, are not all clean is
    // then filtered again from sanitised copies. Both ways give the same values to the same
    // kernel, so the output does not depend on which was taken.
    std::vector<uint8_t> rowClean(size_t(height), 0);
    const bool tryInPlace = kMaskedEdges;
    auto filterBands = [&](const std::vector<int>& list, bool inPlace) {
        ctx.parallel->forRange(
            0, int(list.size()),
            [&](int j0, int j1) {
                // Scratch for the planes this band computes or copies (a single signal's
                // exactly those it uses).
                const int limit = inPlace ? kComputedPlanes[signals] : kPlaneCount;
                auto used = [&](int k) {
                    return signals == 2 || (k != L2 && k != INVL2 && k < R2);
                };
                int planes = 0;
                for (int k = 0; k < limit; ++k) planes += used(k);
                auto lease = arena.acquire(size_t(planes), bandPixels);
                float* scratch[kPlaneCount] = {};
                for (int k = 0, next = 0; k < limit; ++k)
                    if (used(k)) scratch[k] = lease[size_t(next++)] + margin;
                std::vector<float> vcol(static_cast<size_t>(width));
                for (int j = j0; j < j1; ++j) {
                    const int i = list[size_t(j)];
                    const int y0 = i * band, y1 = std::min(height, y0 + band);
                    const int r0 = std::max(0, y0 - reach), r1 = std::min(height, y1 + reach);
                    // The 3x3 terms of the band's rows read one row beyond them: inside the reach.
                    const int base = r0, p1 = r1;
                    // In place: the input planes from row `base` on, rows `width` apart, and
                    // scratch only for the computed planes; else every plane in scratch, rows
                    // `pitch` apart with zeroed margins.
                    const size_t bandPitch = inPlace ? size_t(width) : pitch;
                    float* P[kPlaneCount];
                    std::copy_n(scratch, kPlaneCount, P);
                    auto off = [&](int y) { return size_t(y - base) * bandPitch; };
                    const int32_t* bandIds =
                        ids ? reinterpret_cast<const int32_t*>(P[ID]) : nullptr;
                    if (inPlace) {
                        for (int c = 0; c < 3; ++c) P[NX + c] = normal.row(c, base);
                        P[Z] = depth.row(0, base);
                        if (ids) bandIds = ids + size_t(base) * size_t(width);
                        for (int g = 0; g < signals; ++g) {
                            const int* rgb = kRgb[g];
                            for (int c = 0; c < 3; ++c) P[rgb[c]] = b[g]->color.row(c, base);
                            if (checkVar) P[kVarPlane[g]] = b[g]->var->row(0, base);
                            for (int y = base; y < p1; ++y) {
                                const size_t o = off(y);
                                lumaRow(P[rgb[0]] + o, P[rgb[1]] + o, P[rgb[2]] + o, P[kLum[g]] + o,
                                        width);
                            }
                        }
                    }
                    // Margins: zero (finite: a tap outside the row has weight 0, which multiplies
                    // them).
                    for (int k = 0; k < kPlaneCount && !inPlace && !kMaskedEdges; ++k) {
                        if (!P[k]) continue;  // a plane this signal count does not use
                        std::fill_n(P[k] - margin, margin, 0.f);
                        for (int y = base; y < p1; ++y)
                            std::fill_n(P[k] + off(y) + width, margin, 0.f);
                    }
                    // Pass 1: sanitised copies and luminance (inputs may hold NaN/Inf; nothing
                    // below may). One plane per loop: two streams each, so every loop vectorises.
                    for (int y = base; y < p1 && !inPlace; ++y) {
                        const size_t o = off(y);
                        for (int c = 0; c < 3; ++c)
                            copySanitized(normal.row(c, y), P[NX + c] + o, width,
                                          px::sanitizeNormal);
                        copySanitized(depth.row(0, y), P[Z] + o, width, px::sanitizeDepth);
                        if (ids)
                            std::copy_n(ids + size_t(y) * size_t(width), width,
                                        reinterpret_cast<int32_t*>(P[ID]) + o);
                        for (int g = 0; g < signals; ++g) {
                            const int* rgb = kRgb[g];
                            for (int c = 0; c < 3; ++c)
                                copySanitized(b[g]->color.row(c, y), P[rgb[c]] + o, width,
                                              [](float v) { return px::sanitize(v); });
                            if (checkVar)
                                copySanitized(
                                    b[g]->var->row(0, y), P[kVarPlane[g]] + o, width,
                                    [](float v) { return px::sanitizePositive(v, kMaxVariance); });
                            lumaRow(P[rgb[0]] + o, P[rgb[1]] + o, P[rgb[2]] + o, P[kLum[g]] + o,
                                    width);
                        }
                    }
                    // Pass 2: depth gradient (edge-preserving one-sided differences) and the
                    // luminance weight's 1 / (sigma_l sqrt(g3x3(Var)) + eps) with a 3x3 Gaussian
                    // prefilter (SVGF section 4.4), renormalised at the image border. Both weigh
                    // only the centre pixel p, never a tap q, so only the band's own rows need
                    // them, not its halo.
                    for (int y = y0; y < y1; ++y) {
                        const size_t o = off(y);
                        const bool up = y > 0, down = y + 1 < height;
                        const float* z = P[Z] + o;
                        gradientRow(z, up ? z - bandPitch : z, down ? z + bandPitch : z, P[GX] + o,
                                    P[GY] + o, width, up, down);
                        for (int g = 0; g < signals; ++g) {
                            float* invL = P[kInvL[g]] + o;
                            if (!checkVar) {
                                std::fill(invL, invL + width,
                                          1.f / (settings[g].sigmaColor + kEpsL));
                                continue;
                            }
                            // Separable 3x3 Gaussian (1/4, 1/2, 1/4)^2: vertical, then
                            // horizontal; weights of taps outside the image are dropped and the
                            // rest renormalised.
                            const float* v = P[kVarPlane[g]] + o;
                            const float* va = up ? v - bandPitch : v;
                            const float* vb = down ? v + bandPitch : v;
                            const float wa = up ? 0.25f : 0.f, wb = down ? 0.25f : 0.f;
                            const float vNorm = 1.f / (0.5f + wa + wb);
                            verticalRow(va, v, vb, wa, wb, vNorm, vcol.data(), width);
                            horizontalInvL(vcol.data(), invL, width, settings[g].sigmaL);
                        }
                    }
                    // Pass 3: the filter itself.
                    auto run = [&](auto id, auto nrm, auto v) {
                        constexpr bool kId = decltype(id)::value, kNormal = decltype(nrm)::value,
                                       kVar = decltype(v)::value;
                        // The default sigma_n = 128 = 2^7 gets a kernel with its seven squarings
                        // unrolled.
                        auto range = [&](auto pair, auto squarings) {
                            filterRange<decltype(pair)::value, decltype(squarings)::value, kId,
                                        kNormal, kVar>(y0, y1, width, bandPitch, height, s, P, base,
                                                       bandIds, b, rowClean.data(), checkVar);
                        };
                        using One = std::integral_constant<int, 1>;
                        using Two = std::integral_constant<int, 2>;
                        using Seven = std::integral_constant<int, 7>;
                        using Zero = std::integral_constant<int, 0>;
                        if (signals == 2)
                            s.sigmaN == 128.f ? range(Two{}, Seven{}) : range(Two{}, Zero{});
                        else
                            s.sigmaN == 128.f ? range(One{}, Seven{}) : range(One{}, Zero{});
                    };
                    using T = std::true_type;
                    using F = std::false_type;
                    if (ids) {
                        if (useNormal)
                            withVar ? run(T{}, T{}, T{}) : run(T{}, T{}, F{});
                        else
                            withVar ? run(T{}, F{}, T{}) : run(T{}, F{}, F{});
                    } else {
                        if (useNormal)
                            withVar ? run(F{}, T{}, T{}) : run(F{}, T{}, F{});
                        else
                            withVar ? run(F{}, F{}, T{}) : run(F{}, F{}, F{});
                    }
                }
            },
            1);
    };
    std::vector<int> all(static_cast<size_t>(bands));
    std::iota(all.begin(), all.end(), 0);
    filterBands(all, tryInPlace);
    if (!tryInPlace) return;
    std::vector<int> dirty;
    for (int i = 0; i < bands; ++i) {
        const int base = std::max(0, i * band - reach);
        const int end = std::min(height, (i + 1) * band + reach);
        if (!std::all_of(rowClean.begin() + base, rowClean.begin() + end,
                         [](uint8_t c) { return c != 0; }))
            dirty.push_back(i);
    }
    if (!dirty.empty()) filterBands(dirty, false);
}

}  // namespace
}  // namespace kestrel::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace kestrel {
namespace {
HWY_EXPORT(filterFast);
}  // namespace
}  // namespace kestrel

using namespace kestrel;

PassDesc ATrousPass::describe() {
    PassDesc d("ATrous",
               "One edge-avoiding A-Trous iteration (SVGF eq. 1-5): 5x5 B-spline taps at multiples"
               " of `step`, weighted by depth, normal, object id and variance-normalised luminance;"
               " variance propagated as sum(w^2 Var) / (sum w)^2.");
    d.input("color", Format::Float3, "illumination to filter")
        .optionalInput("variance", Format::Float,
                       "luminance variance; without it the luminance weight uses sigmaColor")
        .input("depth", Format::Float, "linear view depth")
        .input("normal", Format::Float3, "world-space unit normal")
        .optionalInput("objectId", Format::Int32, "object id: taps on another object get weight 0")
        .output("color", Format::Float3, "filtered illumination")
        .output("variance", Format::Float, "propagated variance (absent without variance input)")
        .fuseOn({"depth", "normal", "objectId"}, PassDesc::FusedOutputs::MayDiffer)
        .paramInt("step", 1, 1, 1024, "tap spacing in pixels (2^iteration)")
        .paramFloat("sigmaZ", 1.0, 0.0, 1e6, "depth weight: tolerance in units of the depth slope")
        .paramFloat("sigmaN", 128.0, 0.0, 1e4, "normal weight exponent on max(0, n_p . n_q)")
        .paramFloat("sigmaL", 4.0, 0.0, 1e6, "luminance weight: tolerance in standard deviations")
        .paramFloat("sigmaColor", 0.6, 1e-6, 1e6,
                    "luminance tolerance (absolute) used when no variance is bound")
        .paramInt("iteration", 0, 0, 1024,
                  "this pass's index in its chain (0 first); with iterations, lets one "
                  "parameter set how many of a chain's passes run")
        .paramInt("iterations", 1024, 1, 1024,
                  "how many iterations the chain runs (a group parameter): a pass with "
                  "iteration >= iterations passes color and variance through and is left out")
        .paramBool("exact", false,
                   "run the plain scalar path (libm exp/pow, no SIMD) to measure what the fast"
                   " path's approximations cost in error; several times slower");
    return d;
}

ATrousPass::ATrousPass(const ParamValues& p) {
    s_.step = int(p.getInt("step"));
    s_.sigmaZ = p.getFloat("sigmaZ");
    s_.sigmaN = p.getFloat("sigmaN");
    s_.sigmaL = p.getFloat("sigmaL");
    s_.sigmaColor = p.getFloat("sigmaColor");
    exact_ = p.getBool("exact");
    skipped_ = p.getInt("iteration") >= p.getInt("iterations");
}

void ATrousPass::resolve(ResolveContext& rc) {
    s_.depthPrecision = depthPrecision(rc);
    if (skipped_) {  // beyond the chain's iteration count: an identity, left out by the compiler
        rc.forward("color", "color");
        if (rc.isBound("variance")) rc.forward("variance", "variance");
    }
    varianceBound_ = rc.isBound("variance");
    if (!varianceBound_) {
        rc.setAbsent("variance", "no variance input");
        rc.note("no variance input: luminance weight uses the fixed sigmaColor");
    }
}

std::string ATrousPass::fusionKey() const {
    if (exact_ || skipped_) return {};
    // Everything the shared geometric work depends on; sigmaL and sigmaColor are per signal.
    // A pair filters both signals with or both without a variance.
    char key[128];
    std::snprintf(key, sizeof key, "step=%d sigmaZ=%a sigmaN=%a depthPrecision=%a variance=%d",
                  s_.step, double(s_.sigmaZ), double(s_.sigmaN), double(s_.depthPrecision),
                  int(varianceBound_));
    return key;
}

namespace {
/// Whether two passes' bindings can be filtered as one pair: the same geometry images and both
/// with or both without a variance input (the kernel's variants are per pair). Their variance
/// outputs may differ: the pair then filters both variances and stores the one that is bound
/// (the specular chain's last iteration, whose variance nobody reads, pairs with the diffuse
/// chain's third).
bool pairable(const Bindings& a, const Bindings& b) {
    return a.depth.planes == b.depth.planes && a.normal.planes == b.normal.planes &&
           a.ids == b.ids && (a.var == nullptr) == (b.var == nullptr);
}
}  // namespace

void ATrousPass::executeFused(FrameContext& ctx, std::span<Pass* const> passes,
                              std::span<PassIO* const> ios) {
    // Pairs share each tap's depth, normal and object-id work (NRD filters diffuse and
    // specular together the same way); an odd one out runs alone.
    size_t i = 0;
    for (; i + 1 < ios.size(); i += 2) {
        const Bindings b0(*ios[i]), b1(*ios[i + 1]);
        if (!pairable(b0, b1)) {
            passes[i]->execute(ctx, *ios[i]);
            passes[i + 1]->execute(ctx, *ios[i + 1]);
            continue;
        }
        const Bindings* b[2] = {&b0, &b1};
        const Settings settings[2] = {static_cast<const ATrousPass&>(*passes[i]).s_,
                                      static_cast<const ATrousPass&>(*passes[i + 1]).s_};
        HWY_DYNAMIC_DISPATCH(filterFast)(ctx, b, 2, settings, ios[i]->idlePlanes());
    }
    if (i < ios.size()) passes[i]->execute(ctx, *ios[i]);
}

void ATrousPass::execute(FrameContext& ctx, PassIO& io) {
    if (!exact_) {
        const Bindings b0(io);
        const Bindings* b[1] = {&b0};
        HWY_DYNAMIC_DISPATCH(filterFast)(ctx, b, 1, &s_, io.idlePlanes());
        return;
    }
    const Bindings b(io);
    const reference::ATrousInputs in{&b.color,  b.var,         &b.depth,         &b.normal,
                                     b.idView,  s_.step,       s_.sigmaZ,        s_.sigmaN,
                                     s_.sigmaL, s_.sigmaColor, s_.depthPrecision};
    ctx.parallelRows(ctx.extent.height,
                     [&](int y0, int y1) { reference::atrous(in, b.outColor, b.outVar, y0, y1); });
}
#endif  // HWY_ONCE
