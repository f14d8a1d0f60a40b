// The fast path of one A-Trous iteration (ATrousPass.cpp declares and resolves the pass).
// Compiled once per SIMD target (hwy/foreach_target.h re-includes this file for each one); the
// per-target kernels live in kestrel::N_<TARGET>, and the HWY_ONCE part at the end picks the
// best target of the running CPU (HWY_DYNAMIC_DISPATCH).
#include "ATrousKernels.h"

#include <kestrel/PixelMath.h>
#include <kestrel/Scratch.h>

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <numeric>
#include <vector>

#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "ATrousKernels.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep
// After foreach_target.h: once per target.
#include <hwy/highway.h>
#include <kestrel/SimdMath.h>

#include "ATrousBands-inl.h"

HWY_BEFORE_NAMESPACE();
namespace kestrel::HWY_NAMESPACE {
namespace {

constexpr float kH[5] = {1.f / 16.f, 1.f / 4.f, 3.f / 8.f, 1.f / 4.f, 1.f / 16.f};
constexpr float kEpsZRel = 1e-5f;  // depth tolerance floor relative to z: float depth noise
constexpr float kEpsZAbs = 1e-8f;
constexpr float kMinDot = 1e-30f;
constexpr float kZeroWeight = -1e4f;  // log2 weight penalty: fastExp2 returns exactly 0
constexpr float kLn2 = 0.693147180559945f;

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
/// and sanitizePositive). One function of ~240 lines, a kernel: the centres' terms, the
/// accumulators and the taps lambda share registers through the 24 taps, which functions of
/// their own would pass through memory (the block loop is this pass's whole cost).
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
                 float* const* P, int base, const int32_t* ids, const ATrousBindings* const* b,
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

/// Pass 3: the filter itself, the kernel variant for the bindings and settings.
void filterBand(const Job& job, const Band& band, uint8_t* rowClean) {
    const ATrousPass::Settings& s = job.s;
    auto run = [&](auto id, auto nrm, auto v) {
        constexpr bool kId = decltype(id)::value, kNormal = decltype(nrm)::value,
                       kVar = decltype(v)::value;
        // The default sigma_n = 128 = 2^7 gets a kernel with its seven squarings unrolled.
        auto range = [&](auto pair, auto squarings) {
            filterRange<decltype(pair)::value, decltype(squarings)::value, kId, kNormal, kVar>(
                band.y0, band.y1, job.width, band.pitch, job.height, s, band.P, band.base, band.ids,
                job.b, rowClean, job.checkVar);
        };
        using One = std::integral_constant<int, 1>;
        using Two = std::integral_constant<int, 2>;
        using Seven = std::integral_constant<int, 7>;
        using Zero = std::integral_constant<int, 0>;
        if (job.signals == 2)
            s.sigmaN == 128.f ? range(Two{}, Seven{}) : range(Two{}, Zero{});
        else
            s.sigmaN == 128.f ? range(One{}, Seven{}) : range(One{}, Zero{});
    };
    using T = std::true_type;
    using F = std::false_type;
    const bool withVar = job.withVar;
    if (job.ids) {
        if (job.useNormal)
            withVar ? run(T{}, T{}, T{}) : run(T{}, T{}, F{});
        else
            withVar ? run(T{}, F{}, T{}) : run(T{}, F{}, F{});
    } else {
        if (job.useNormal)
            withVar ? run(F{}, T{}, T{}) : run(F{}, T{}, F{});
        else
            withVar ? run(F{}, F{}, T{}) : run(F{}, F{}, F{});
    }
}

/// The bands in `list`, read in place or from sanitised copies.
void filterBands(FrameContext& ctx, ScratchArena& arena, const Job& job,
                 const std::vector<int>& list, bool inPlace, uint8_t* rowClean) {
    ctx.parallel->forRange(
        0, int(list.size()),
        [&](int j0, int j1) {
            // Scratch for the planes this band computes or copies (a single signal's exactly
            // those it uses).
            const int limit = inPlace ? kComputedPlanes[job.signals] : kPlaneCount;
            auto used = [&](int k) {
                return job.signals == 2 || (k != L2 && k != INVL2 && k < R2);
            };
            int planes = 0;
            for (int k = 0; k < limit; ++k) planes += used(k);
            auto lease = arena.acquire(size_t(planes), job.bandPixels);
            float* scratch[kPlaneCount] = {};
            for (int k = 0, next = 0; k < limit; ++k)
                if (used(k)) scratch[k] = lease[size_t(next++)] + job.margin;
            std::vector<float> vcol(static_cast<size_t>(job.width));
            for (int j = j0; j < j1; ++j) {
                const int i = list[size_t(j)];
                Band band;
                band.y0 = i * job.band;
                band.y1 = std::min(job.height, band.y0 + job.band);
                band.base = std::max(0, band.y0 - job.reach);
                band.p1 = std::min(job.height, band.y1 + job.reach);
                // In place: rows `width` apart, scratch only for the computed planes; else
                // every plane in scratch, rows `pitch` apart with zeroed margins.
                band.pitch = inPlace ? size_t(job.width) : job.pitch;
                std::copy_n(scratch, kPlaneCount, band.P);
                band.ids = job.ids ? reinterpret_cast<const int32_t*>(band.P[ID]) : nullptr;
                if (inPlace)
                    bindInPlace(job, band);
                else
                    copySanitised(job, band);
                centreTerms(job, band, vcol.data());
                filterBand(job, band, rowClean);
            }
        },
        1);
}

/// The fast path (everything but `exact`) for this target: one signal, or a fused pair
/// (`signals` = 2) sharing the first's geometry and geometric settings; each signal's own
/// settings give its luminance weight (sigmaL, sigmaColor). Band scratch comes from the step's
/// idle planes where they suffice (ScratchArena).
void filterFast(FrameContext& ctx, const ATrousBindings* const* b, int signals,
                const ATrousPass::Settings* settings, std::span<float* const> idle) {
    ScratchArena arena(idle, ctx.extent.pixels());
    const Job job(ctx, b, signals, settings);
    // Inputs are nearly always clean (the previous iteration's output, the loader's geometry),
    // so every band first reads them in place, without copying nine planes into scratch
    // (1080p, 1 thread, min of 5, three alternating rounds: step 1 51-52 -> 44-45 ms, step 16
    // 54-56 -> 44-48; 2 threads 27-32 -> 23-33, noisier), while the kernel checks each centre
    // pixel's inputs (filterBlocks). A band whose rows, its halo included, are not all clean is
    // then filtered again from sanitised copies. Both ways give the same values to the same
    // kernel, so the output does not depend on which was taken.
    std::vector<uint8_t> rowClean(size_t(job.height), 0);
    const bool tryInPlace = kMaskedEdges;
    std::vector<int> all(static_cast<size_t>(job.bands));
    std::iota(all.begin(), all.end(), 0);
    filterBands(ctx, arena, job, all, tryInPlace, rowClean.data());
    if (!tryInPlace) return;
    std::vector<int> dirty;
    for (int i = 0; i < job.bands; ++i) {
        const int base = std::max(0, i * job.band - job.reach);
        const int end = std::min(job.height, (i + 1) * job.band + job.reach);
        if (!std::all_of(rowClean.begin() + base, rowClean.begin() + end,
                         [](uint8_t c) { return c != 0; }))
            dirty.push_back(i);
    }
    if (!dirty.empty()) filterBands(ctx, arena, job, dirty, false, rowClean.data());
}

}  // namespace
}  // namespace kestrel::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace kestrel {
namespace {
HWY_EXPORT(filterFast);
}  // namespace

void atrousFilterFast(FrameContext& ctx, const ATrousBindings* const* b, int signals,
                      const ATrousPass::Settings* settings, std::span<float* const> idle) {
    HWY_DYNAMIC_DISPATCH(filterFast)(ctx, b, signals, settings, idle);
}
}  // namespace kestrel
#endif  // HWY_ONCE
