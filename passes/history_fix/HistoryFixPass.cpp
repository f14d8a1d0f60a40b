#include "HistoryFixPass.h"

#include <kestrel/PixelMath.h>

#include <algorithm>
#include <cmath>
#include <cstdint>

using namespace kestrel;

namespace {

/// B3-spline taps (as A-Trous) for a pixel with no history: a smooth 5x5 footprint, the centre
/// weighted most; a pixel with some history, which keeps part of its own colour, takes the 3x3
/// binomial: the speckles are the pixels with no history, and the 5x5 on the others cost
/// 0.02-0.05 dB and 2.8x the taps (frames 2 and 3 after every cut).
constexpr float kKernel5[5] = {1.f / 16, 1.f / 4, 3.f / 8, 1.f / 4, 1.f / 16};
constexpr float kKernel3[5] = {0.f, 1.f / 4, 1.f / 2, 1.f / 4, 0.f};

/// The inputs as planes of w x h floats (ids as int32), sanitised where they are read.
struct Planes {
    int w, h;
    const float *c[3], *length, *depth, *n[3];
    const int32_t* ids;  ///< null without the objectId input

    float z(size_t i) const { return px::sanitizeDepth(depth[i]); }
    float nrm(int k, size_t i) const { return px::sanitizeNormal(n[k][i]); }
};

/// max(0, dot)^p: repeated squaring for the powers of two (8 by default), else std::pow.
float normalWeight(float dot, float p) {
    const float d = std::min(dot, 1.f);
    if (p == 8.f) {
        const float d2 = d * d, d4 = d2 * d2;
        return d4 * d4;
    }
    return std::pow(d, p);
}

/// The depth slope through a pixel from its neighbours' differences b and f: the smaller where
/// both agree in sign (a slope, or a slope beside a depth edge), else 0 (a ridge, a valley, a
/// pixel standing alone in front of a wall, whose differences are no slope at all).
float slope(float prev, float cur, float next, bool hasPrev, bool hasNext) {
    const float b = hasPrev ? cur - prev : 0.f, f = hasNext ? next - cur : 0.f;
    if (!hasPrev) return f;
    if (!hasNext) return b;
    if ((b > 0.f) != (f > 0.f)) return 0.f;
    return std::fabs(b) <= std::fabs(f) ? b : f;
}

/// The stride for a history length: `stride` at 1, falling linearly towards 1 at `frames`
/// (never below 1: the blend below, not the stride, lets go of the fill).
int strideFor(float hl, const HistoryFixPass::Settings& s) {
    const float t = (s.frames - std::max(hl, 1.f)) / std::max(s.frames - 1.f, 1e-6f);
    return std::max(1, int(std::lround(t * float(s.stride))));
}

/// How much of the pixel's own accumulated colour is kept: 0 at historyLength 1, rising linearly
/// to 1 at `frames`. A step (fill or keep) blurred pixels two frames old as much as new ones:
/// 0.3 dB lost on frame 2 of every zoo scene, and again after each anti-lag reset.
float ownShare(float hl, const HistoryFixPass::Settings& s) {
    if (!(hl < s.frames) || s.frames <= 1.f) return 1.f;
    return std::clamp((hl - 1.f) / (s.frames - 1.f), 0.f, 1.f);
}

/// Without the normal weight a tap is still skipped when its normal faces away from the
/// pixel's (the other side of a sheet, a mirror's sky): beyond perpendicular, with a margin for
/// the features' rounding (the perpendicular normals of a window's reflected ground and wall
/// meet at dot products within 1e-3 of 0).
constexpr float kFacingAway = -0.1f;

/// The neighbours' share of a fill's weight below which the pixel counts as isolated by its
/// normal: it would keep over three quarters of its own 1-spp sample.
constexpr float kIsolated = 0.25f;

/// The filled colour of pixel (x, y) with tap spacing `step` > 0 and `radius` 1 (3x3) or 2
/// (5x5), into out[3]; returns the neighbours' share of the weight. `normals`: weight the taps
/// by the normal too, else by depth, object id and history length, skipping only the taps
/// facing away.
float fillPixel(const Planes& p, const HistoryFixPass::Settings& s, int x, int y, int step,
                int radius, bool normals, float out[3]) {
    const float* kKernel = radius == 2 ? kKernel5 : kKernel3;
    const int w = p.w, h = p.h;
    const size_t ip = size_t(y) * size_t(w) + size_t(x);
    const float zp = p.z(ip);
    const bool l = x > 0, r = x + 1 < w, u = y > 0, d = y + 1 < h;
    const float gx = slope(l ? p.z(ip - 1) : 0, zp, r ? p.z(ip + 1) : 0, l, r);
    const float gy = slope(u ? p.z(ip - size_t(w)) : 0, zp, d ? p.z(ip + size_t(w)) : 0, u, d);
    const int32_t id = p.ids ? p.ids[ip] : 0;
    const float n0 = p.nrm(0, ip), n1 = p.nrm(1, ip), n2 = p.nrm(2, ip);
    float sw = 0.f, sc[3] = {0.f, 0.f, 0.f}, own = 0.f;
    for (int j = -radius; j <= radius; ++j) {
        const int yq = y + j * step;
        if (yq < 0 || yq >= h) continue;
        for (int i = -radius; i <= radius; ++i) {
            const int dx = i * step, dy = j * step, xq = x + dx;
            if (xq < 0 || xq >= w) continue;
            const size_t q = size_t(yq) * size_t(w) + size_t(xq);
            float wt = kKernel[i + 2] * kKernel[j + 2];
            if (i != 0 || j != 0) {
                if (p.ids && p.ids[q] != id) continue;
                const float zq = p.z(q);
                if (zq >= kBackgroundDepth) continue;
                // The depth the surface's slope predicts there, within depthSlack of the depth
                // per pixel of distance (a plane seen at a grazing angle, a gentle curve).
                const float predicted = zp + gx * float(dx) + gy * float(dy);
                const float tolerance = s.depthSlack * zp * float(std::abs(dx) + std::abs(dy));
                if (!(std::fabs(zq - predicted) <= tolerance)) continue;
                const float dot = n0 * p.nrm(0, q) + n1 * p.nrm(1, q) + n2 * p.nrm(2, q);
                if (normals) {
                    if (!(dot > 0.f)) continue;
                    wt *= normalWeight(dot, s.normalPower);
                } else if (!(dot >= kFacingAway)) {
                    continue;
                }
            }
            // Each tap counts as the samples its history holds (its noise falls as 1 / length).
            wt *= px::sanitizePositive(p.length[q], 1e6f) + 1e-3f;
            if (i == 0 && j == 0) own = wt;
            sw += wt;
            for (int c = 0; c < 3; ++c) sc[c] += wt * px::sanitize(p.c[c][q]);
        }
    }
    for (int c = 0; c < 3; ++c) out[c] = sc[c] / sw;  // sw > 0: the centre always counts
    return (sw - own) / sw;
}

}  // namespace

HistoryFixPass::Declaration::Declaration()
    : kestrel::Declaration<Params>(
          "HistoryFix",
          "Fills pixels with a short history (disocclusions, cuts, the first frames, a "
          "history anti-lag shortened) from their neighbours on the same surface: a 5x5 "
          "B3-spline footprint (3x3 binomial once the pixel has some history) whose stride "
          "shrinks from `stride` at historyLength 1 "
          "towards 1 at `frames`, weighted by depth, normal, object id and each neighbour's "
          "history length, never by luminance (after NRD ReBLUR's history fix); the pixel "
          "keeps (historyLength - 1) / (frames - 1) of its own colour. Pixels with "
          "`frames` or more pass unchanged.") {
    color = input("color", Format::Float3, "temporally accumulated illumination");
    historyLength =
        input("historyLength", Format::Float, "history length per pixel (1: no history)");
    depth = input("depth", Format::Float, "linear view depth");
    normal = input("normal", Format::Float3, "world-space normal");
    objectId =
        optionalInput("objectId", Format::Int32, "object id: taps on another object are skipped");
    colorOut =
        output("color", Format::Float3, "the illumination, filled where the history is short");
    param("frames", &Params::frames, 1.0, 1e6,
          "pixels whose history is shorter are filled (4: VarianceEstimation's "
          "minHistoryLength, below which the variance is spatial too)");
    param("stride", &Params::stride, 1, 64,
          "tap spacing in pixels at historyLength 1 (the footprint is 4 strides wide)");
    param("normalPower", &Params::normalPower, 0.0, 1e4,
          "normal weight exponent: max(0, n_p . n_q)^p (looser than A-Trous' 128: a "
          "curved surface's neighbours must count)");
    paramDecimal("depthSlack", &Params::depthSlack, 0.0, 1e6,
                 "relative depth tolerance per pixel of distance, beyond the depth slope");
}

const HistoryFixPass::Declaration& HistoryFixPass::declaration() {
    static const Declaration d;
    return d;
}

namespace {
HistoryFixPass::Settings settingsOf(const HistoryFixPass::Params& p) {
    return {p.frames, p.stride, p.normalPower, p.depthSlack};
}
}  // namespace

HistoryFixPass::HistoryFixPass(const ParamValues& values)
    : s_(settingsOf(declaration().read(values))) {}

void HistoryFixPass::execute(FrameContext& ctx, PassIO& io) {
    const Declaration& d = declaration();
    const ImageView &color = io.input(d.color), &normal = io.input(d.normal);
    const int w = ctx.extent.width, h = ctx.extent.height;
    const Planes p{w,
                   h,
                   {color.channel(0), color.channel(1), color.channel(2)},
                   io.input(d.historyLength).channel(0),
                   io.input(d.depth).channel(0),
                   {normal.channel(0), normal.channel(1), normal.channel(2)},
                   io.has(d.objectId) ? io.input(d.objectId).ints() : nullptr};
    const ImageView& out = io.output(d.colorOut);
    float* o[3] = {out.channel(0), out.channel(1), out.channel(2)};
    ctx.parallelRows(h, [&](int y0, int y1) {
        for (int y = y0; y < y1; ++y) {
            const size_t row = size_t(y) * size_t(w);
            for (int c = 0; c < 3; ++c)  // most pixels have a history: copied, sanitised
                for (size_t i = row; i < row + size_t(w); ++i) o[c][i] = px::sanitize(p.c[c][i]);
            for (int x = 0; x < w; ++x) {
                const size_t i = row + size_t(x);
                const float hl = px::sanitizePositive(p.length[i], 1e6f);
                const float own = ownShare(hl, s_);
                if (own >= 1.f || p.z(i) >= kBackgroundDepth) continue;
                float c[3];
                const int step = strideFor(hl, s_), radius = hl < 2.f ? 2 : 1;
                // A pixel whose neighbours' normals all differ from its own kept its 1-spp sample
                // (often 0), and A-Trous' normal test isolates it as well: a speckle. Cycles'
                // Denoising Normal (the loader's normal) follows each sample through glass and
                // mirrors, so on a window one sample's normal is the ground it reflects, its
                // neighbours' the wall across the street (of frame 1's speckles, 69 of 125 on
                // blender-street, 115 of 221 on blender-street-defaults and 17 of 162 on the
                // showroom had neighbours holding under a quarter of the weight). There the fill
                // is redone on depth (the surface's plane), object id and history length, as NRD
                // ReBLUR's history fix weighs its taps by geometry, the normal only skipping taps
                // that face away. Under half (not a quarter) also took the zoo rooms' curved
                // walls and mirrors' edges, whose normals are no noise: 0.05 dB lost on
                // room-lamp's texture and on blender-street's reflections (frames 5-12).
                if (fillPixel(p, s_, x, y, step, radius, true, c) < kIsolated)
                    fillPixel(p, s_, x, y, step, radius, false, c);
                for (int k = 0; k < 3; ++k) o[k][i] = own * o[k][i] + (1.f - own) * c[k];
            }
        }
    });
}
